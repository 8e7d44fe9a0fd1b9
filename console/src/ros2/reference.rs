//! The robot's reference pose on the network (`--reference TOPIC`): subscribed in the type given
//! or, by default, in the type the topic is discovered with (looked for once a second until a
//! publisher appears), and read as planar poses with their stamps and variances.

use odocal::kinematics::reference::PoseF64;
use ros2_client::{Context, MessageTypeName, Node, NodeName, NodeOptions, Subscription};

use super::msgs::geometry_msgs::{self, Pose, PoseStamped, PoseWithCovarianceStamped};
use super::msgs::nav_msgs::{self, Odometry};
use super::msgs::{Covariance, TypeName};
use super::{default_qos, topic_name};
use crate::online::ReferenceType;

/// One reference sample as received: its stamp (seconds on the stamp's clock), the planar pose,
/// and the x, y and yaw variances of its covariance (`None` for a plain pose).
pub type Sample = (f64, PoseF64, Option<(f64, f64, f64)>);

enum Sub {
    PoseCov(Subscription<PoseWithCovarianceStamped>),
    Pose(Subscription<PoseStamped>),
    Odometry(Subscription<Odometry>),
}

/// The reference topic, subscribed once its type is known.
pub struct Reference {
    context: Context,
    ns: String,
    topic: String,
    node_name: String,
    ty: Option<ReferenceType>,
    sub: Option<(Sub, Node)>,
}

fn planar(p: &Pose) -> PoseF64 {
    PoseF64::new(p.position.x, p.position.y, p.orientation.yaw())
}

fn variances(c: &Covariance) -> Option<(f64, f64, f64)> {
    Some((c.0[0], c.0[7], c.0[35]))
}

impl Reference {
    /// The reference `topic` in namespace `ns`, of type `ty` (`None`: as discovered).
    pub fn new(
        context: Context,
        ns: &str,
        topic: &str,
        node_name: &str,
        ty: Option<ReferenceType>,
    ) -> Reference {
        Reference {
            context,
            ns: ns.to_string(),
            topic: topic.to_string(),
            node_name: format!("{node_name}_reference"),
            ty,
            sub: None,
        }
    }

    /// The type the topic is subscribed in, once known.
    pub fn kind(&self) -> Option<ReferenceType> {
        self.sub.as_ref().and(self.ty)
    }

    /// The topic's name as given.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// Subscribes, when not yet done and the type is known (given, or discovered now).
    ///
    /// # Errors
    /// The topic's name or the subscription is refused by the middleware, as text.
    pub fn resolve(&mut self) -> Result<(), String> {
        if self.sub.is_some() {
            return Ok(());
        }
        let name = topic_name(&self.ns, &self.topic)?;
        if self.ty.is_none() {
            let dds = name.to_dds_name(
                "rt",
                &NodeName::new("/", "n").map_err(|e| format!("{e:?}"))?,
                "",
            );
            self.ty = self
                .context
                .discovered_topics()
                .iter()
                .filter(|t| t.name == dds)
                .find_map(|t| ReferenceType::of_dds_type(&t.type_name));
        }
        let Some(ty) = self.ty else {
            return Ok(());
        };
        let mut node = self
            .context
            .new_node(
                NodeName::new(&self.ns, &self.node_name).map_err(|e| format!("{e:?}"))?,
                NodeOptions::new().enable_rosout(false),
            )
            .map_err(|e| format!("ROS 2 node: {e:?}"))?;
        let qos = default_qos(10);
        let (pkg, tyname): TypeName = match ty {
            ReferenceType::PoseCov => geometry_msgs::POSE_WITH_COVARIANCE_STAMPED,
            ReferenceType::Pose => geometry_msgs::POSE_STAMPED,
            ReferenceType::Odometry => nav_msgs::ODOMETRY,
        };
        let topic = node
            .create_topic(&name, MessageTypeName::new(pkg, tyname), &qos)
            .map_err(|e| format!("topic {}: {e:?}", self.topic))?;
        let err = |e| format!("subscription {}: {e:?}", self.topic);
        let sub = match ty {
            ReferenceType::PoseCov => Sub::PoseCov(
                node.create_subscription(&topic, Some(qos.clone()))
                    .map_err(err)?,
            ),
            ReferenceType::Pose => Sub::Pose(
                node.create_subscription(&topic, Some(qos.clone()))
                    .map_err(err)?,
            ),
            ReferenceType::Odometry => Sub::Odometry(
                node.create_subscription(&topic, Some(qos.clone()))
                    .map_err(err)?,
            ),
        };
        self.sub = Some((sub, node));
        Ok(())
    }

    /// Every sample received since the last call, oldest first.
    pub fn take(&self) -> Vec<Sample> {
        let mut out = Vec::new();
        let Some((sub, _)) = &self.sub else {
            return out;
        };
        loop {
            let s = match sub {
                Sub::PoseCov(s) => s.take().ok().flatten().map(|(m, _)| {
                    (
                        m.header.stamp.secs(),
                        planar(&m.pose.pose),
                        variances(&m.pose.covariance),
                    )
                }),
                Sub::Pose(s) => s
                    .take()
                    .ok()
                    .flatten()
                    .map(|(m, _)| (m.header.stamp.secs(), planar(&m.pose), None)),
                Sub::Odometry(s) => s.take().ok().flatten().map(|(m, _)| {
                    (
                        m.header.stamp.secs(),
                        planar(&m.pose.pose),
                        variances(&m.pose.covariance),
                    )
                }),
            };
            match s {
                Some(s) => out.push(s),
                None => return out,
            }
        }
    }
}
