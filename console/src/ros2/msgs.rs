//! The ROS 2 messages the bridge exchanges, as plain structs whose serde order is the field
//! order of the `.msg` definitions (RustDDS writes them as CDR, as every ROS 2 middleware does).
//! Each module is named after its ROS package; the DDS type name of a message `pkg/msg/Name` is
//! `pkg::msg::dds_::Name_` ([`type_name`]).

use serde::de::{SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A row-major 6×6 covariance (`float64[36]`): a fixed-size CDR array, written without a length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Covariance([0.0; 36])
    }
}

impl Serialize for Covariance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("36 float64")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (i, v) in c.iter_mut().enumerate() {
                    *v = seq
                        .next_element()?
                        .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, V)
    }
}

/// `(package, name)` of a message for [`ros2_client::MessageTypeName`].
pub type TypeName = (&'static str, &'static str);

/// The DDS type name ROS 2 gives a message type (`nav_msgs::msg::dds_::Odometry_`), as
/// `ros2_client::MessageTypeName` forms it.
#[cfg(test)]
pub fn type_name((package, name): TypeName) -> String {
    format!("{package}::msg::dds_::{name}_")
}

pub mod builtin_interfaces {
    use super::*;
    /// `builtin_interfaces/msg/Time`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Time {
        pub sec: i32,
        pub nanosec: u32,
    }
    impl Time {
        /// Seconds since the Unix epoch as a `Time` (an `f64` of today's epoch seconds holds
        /// them to 0.24 µs).
        pub fn from_secs(t: f64) -> Time {
            let sec = t.floor();
            let ns = ((t - sec) * 1e9).round().min(999_999_999.0);
            Time {
                sec: sec as i32,
                nanosec: ns as u32,
            }
        }
        /// Seconds since the Unix epoch.
        pub fn secs(&self) -> f64 {
            f64::from(self.sec) + f64::from(self.nanosec) * 1e-9
        }
    }
}

pub mod std_msgs {
    use super::builtin_interfaces::Time;
    use super::*;
    /// `std_msgs/msg/Header`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Header {
        pub stamp: Time,
        pub frame_id: String,
    }
}

pub mod geometry_msgs {
    use super::std_msgs::Header;
    use super::*;
    pub const TWIST: TypeName = ("geometry_msgs", "Twist");
    pub const TWIST_STAMPED: TypeName = ("geometry_msgs", "TwistStamped");
    pub const POSE_STAMPED: TypeName = ("geometry_msgs", "PoseStamped");
    pub const POSE_WITH_COVARIANCE_STAMPED: TypeName =
        ("geometry_msgs", "PoseWithCovarianceStamped");

    /// `geometry_msgs/msg/Point`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Point {
        pub x: f64,
        pub y: f64,
        pub z: f64,
    }
    /// `geometry_msgs/msg/Vector3`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Vector3 {
        pub x: f64,
        pub y: f64,
        pub z: f64,
    }
    /// `geometry_msgs/msg/Quaternion`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Quaternion {
        pub x: f64,
        pub y: f64,
        pub z: f64,
        pub w: f64,
    }
    impl Quaternion {
        /// The rotation by `yaw` radians about z.
        pub fn from_yaw(yaw: f64) -> Quaternion {
            let (s, c) = (0.5 * yaw).sin_cos();
            Quaternion {
                x: 0.0,
                y: 0.0,
                z: s,
                w: c,
            }
        }

        /// The rotation's angle about z (the yaw of a planar pose), radians in (−π, π].
        pub fn yaw(&self) -> f64 {
            (2.0 * (self.w * self.z + self.x * self.y))
                .atan2(1.0 - 2.0 * (self.y * self.y + self.z * self.z))
        }
    }
    /// `geometry_msgs/msg/Pose`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Pose {
        pub position: Point,
        pub orientation: Quaternion,
    }
    /// `geometry_msgs/msg/PoseWithCovariance`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct PoseWithCovariance {
        pub pose: Pose,
        pub covariance: Covariance,
    }
    /// `geometry_msgs/msg/PoseStamped` (a motion-capture system's pose).
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct PoseStamped {
        pub header: Header,
        pub pose: Pose,
    }
    /// `geometry_msgs/msg/PoseWithCovarianceStamped` (AMCL's, robot_localization's pose).
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct PoseWithCovarianceStamped {
        pub header: Header,
        pub pose: PoseWithCovariance,
    }
    /// `geometry_msgs/msg/Twist`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Twist {
        pub linear: Vector3,
        pub angular: Vector3,
    }
    impl Twist {
        /// A planar robot's twist: `v` forward (m/s), `w` about z (rad/s).
        pub fn planar(v: f64, w: f64) -> Twist {
            Twist {
                linear: Vector3 {
                    x: v,
                    ..Vector3::default()
                },
                angular: Vector3 {
                    z: w,
                    ..Vector3::default()
                },
            }
        }
    }
    /// `geometry_msgs/msg/TwistStamped`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct TwistStamped {
        pub header: Header,
        pub twist: Twist,
    }
    /// `geometry_msgs/msg/TwistWithCovariance`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct TwistWithCovariance {
        pub twist: Twist,
        pub covariance: Covariance,
    }
    /// `geometry_msgs/msg/Transform`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Transform {
        pub translation: Vector3,
        pub rotation: Quaternion,
    }
    /// `geometry_msgs/msg/TransformStamped`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct TransformStamped {
        pub header: Header,
        pub child_frame_id: String,
        pub transform: Transform,
    }
}

pub mod nav_msgs {
    use super::geometry_msgs::{PoseWithCovariance, TwistWithCovariance};
    use super::std_msgs::Header;
    use super::*;
    pub const ODOMETRY: TypeName = ("nav_msgs", "Odometry");
    /// `nav_msgs/msg/Odometry`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct Odometry {
        pub header: Header,
        pub child_frame_id: String,
        pub pose: PoseWithCovariance,
        pub twist: TwistWithCovariance,
    }
}

pub mod tf2_msgs {
    use super::geometry_msgs::TransformStamped;
    use super::*;
    pub const TF_MESSAGE: TypeName = ("tf2_msgs", "TFMessage");
    /// `tf2_msgs/msg/TFMessage`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct TFMessage {
        pub transforms: Vec<TransformStamped>,
    }
}

pub mod sensor_msgs {
    use super::std_msgs::Header;
    use super::*;
    pub const JOINT_STATE: TypeName = ("sensor_msgs", "JointState");
    /// `sensor_msgs/msg/JointState`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct JointState {
        pub header: Header,
        pub name: Vec<String>,
        pub position: Vec<f64>,
        pub velocity: Vec<f64>,
        pub effort: Vec<f64>,
    }
}

pub mod diagnostic_msgs {
    use super::std_msgs::Header;
    use super::*;
    pub const DIAGNOSTIC_ARRAY: TypeName = ("diagnostic_msgs", "DiagnosticArray");
    /// `DiagnosticStatus.level`: OK.
    pub const OK: u8 = 0;
    /// `DiagnosticStatus.level`: WARN.
    pub const WARN: u8 = 1;
    /// `DiagnosticStatus.level`: ERROR.
    pub const ERROR: u8 = 2;
    /// `diagnostic_msgs/msg/KeyValue`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct KeyValue {
        pub key: String,
        pub value: String,
    }
    /// `diagnostic_msgs/msg/DiagnosticStatus`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct DiagnosticStatus {
        pub level: u8,
        pub name: String,
        pub message: String,
        pub hardware_id: String,
        pub values: Vec<KeyValue>,
    }
    /// `diagnostic_msgs/msg/DiagnosticArray`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct DiagnosticArray {
        pub header: Header,
        pub status: Vec<DiagnosticStatus>,
    }
}

#[cfg(test)]
mod tests {
    use super::builtin_interfaces::Time;
    use super::*;

    #[test]
    fn dds_type_names_follow_ros2() {
        assert_eq!(
            type_name(nav_msgs::ODOMETRY),
            "nav_msgs::msg::dds_::Odometry_"
        );
        assert_eq!(
            type_name(tf2_msgs::TF_MESSAGE),
            "tf2_msgs::msg::dds_::TFMessage_"
        );
    }

    #[test]
    fn times_split_into_seconds_and_nanoseconds() {
        let t = Time::from_secs(1_700_000_000.25);
        assert_eq!(t.sec, 1_700_000_000);
        assert!(t.nanosec.abs_diff(250_000_000) <= 240, "{t:?}");
        assert!((t.secs() - 1_700_000_000.25).abs() < 1e-6);
    }
}
