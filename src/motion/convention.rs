//! How an operator read every measured end pose of a session: the standard frame (x forward, y
//! to the left, heading CCW in the heading unit declared), or one of the consistent mistakes a
//! tape and a square invite. A [`Convention`] re-reads a stored measurement into the standard
//! frame; the measurement itself stays as typed (`convention standard` undoes it). Also the
//! measuring noise an operator declares for those measurements ([`MeasuringNoise`]).

use super::run::Measurement;
use crate::util::text::keyword_eq;

/// A consistent way every run of a session was measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Convention {
    /// x forward, y to the left, heading counter-clockwise: as the board asks.
    #[default]
    Standard,
    /// y to the right on every run: y and the heading negated.
    YRight,
    /// x and y exchanged on every run.
    Swapped,
    /// The heading's sign reversed on every run (clockwise positive).
    HeadingSign,
    /// Headings typed in radians where degrees were read.
    ThetaRadians,
    /// Headings typed in degrees where radians were read.
    ThetaDegrees,
}

impl Convention {
    /// Every convention, the standard one first, then the mistakes in the order they are tried.
    pub const ALL: [Convention; 6] = [
        Convention::Standard,
        Convention::YRight,
        Convention::Swapped,
        Convention::HeadingSign,
        Convention::ThetaRadians,
        Convention::ThetaDegrees,
    ];

    /// Every name, as a refusal lists them.
    pub const NAMES: &str = "standard|y-right|swapped|heading-sign|theta-radians|theta-degrees";

    /// Its name on the wire (`convention y-right`).
    pub fn as_str(self) -> &'static str {
        match self {
            Convention::Standard => "standard",
            Convention::YRight => "y-right",
            Convention::Swapped => "swapped",
            Convention::HeadingSign => "heading-sign",
            Convention::ThetaRadians => "theta-radians",
            Convention::ThetaDegrees => "theta-degrees",
        }
    }

    /// The mistake in a few words, as a reply names it.
    pub fn describe(self) -> &'static str {
        match self {
            Convention::Standard => "x forward, y left, CCW",
            Convention::YRight => "y to the right",
            Convention::Swapped => "x and y swapped",
            Convention::HeadingSign => "heading sign reversed",
            Convention::ThetaRadians => "headings in rad as deg",
            Convention::ThetaDegrees => "headings in deg as rad",
        }
    }

    /// Looks a name up (ASCII case-insensitive).
    pub fn parse(word: &str) -> Option<Convention> {
        Convention::ALL
            .into_iter()
            .find(|c| keyword_eq(c.as_str(), word))
    }

    /// The stored form (one byte).
    pub fn to_byte(self) -> u8 {
        self as u8
    }

    /// Reads the stored form; `None` for a byte no convention has.
    pub fn from_byte(byte: u8) -> Option<Convention> {
        Convention::ALL.get(usize::from(byte)).copied()
    }

    /// `m` as typed under this convention, re-read into the standard frame.
    pub fn reread(self, m: Measurement) -> Measurement {
        const DEG_PER_RAD: f64 = 180.0 / core::f64::consts::PI;
        let Measurement {
            x_m,
            y_m,
            theta_rad,
        } = m;
        match self {
            Convention::Standard => m,
            Convention::YRight => Measurement {
                x_m,
                y_m: -y_m,
                theta_rad: theta_rad.map(|t| -t),
            },
            Convention::Swapped => Measurement {
                x_m: y_m,
                y_m: x_m,
                theta_rad,
            },
            Convention::HeadingSign => Measurement {
                theta_rad: theta_rad.map(|t| -t),
                ..m
            },
            // A radian number read as degrees was scaled by π/180 on the way in.
            Convention::ThetaRadians => Measurement {
                theta_rad: theta_rad.map(|t| t * DEG_PER_RAD),
                ..m
            },
            Convention::ThetaDegrees => Measurement {
                theta_rad: theta_rad.map(|t| t / DEG_PER_RAD),
                ..m
            },
        }
    }
}

/// Accepted declared 1σ of a measured position, metres: 0.1 mm (a calliper on a grid) to 0.5 m
/// (beyond it a square's systematic error cannot be seen at all).
pub const MEASURE_SD_RANGE_M: (f64, f64) = (1e-4, 0.5);

/// Accepted declared 1σ of a measured heading, degrees: 0.01° (motion capture) to 30°.
pub const HEADING_SD_RANGE_DEG: (f64, f64) = (0.01, 30.0);

/// The measuring noise an operator declares: 1σ of a measured end position (each coordinate)
/// and heading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasuringNoise {
    /// 1σ of a measured x or y, metres.
    pub position_m: f64,
    /// 1σ of a measured heading, radians.
    pub heading_rad: f64,
}

/// The declared 1σ of a measured heading by default, degrees: a protractor or a long edge.
pub const DEFAULT_HEADING_SD_DEG: f64 = 0.2;

impl MeasuringNoise {
    /// What the procedure asks for: 1 mm with a tape, [`DEFAULT_HEADING_SD_DEG`] for a heading.
    pub const DEFAULT: MeasuringNoise = MeasuringNoise {
        position_m: 1e-3,
        heading_rad: DEFAULT_HEADING_SD_DEG * core::f64::consts::PI / 180.0,
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_bytes_round_trip() {
        for c in Convention::ALL {
            assert_eq!(Convention::parse(c.as_str()), Some(c));
            assert_eq!(Convention::from_byte(c.to_byte()), Some(c));
        }
        assert_eq!(Convention::parse("Y-RIGHT"), Some(Convention::YRight));
        assert_eq!(Convention::from_byte(6), None);
        let names: std::vec::Vec<&str> = Convention::ALL.iter().map(|c| c.as_str()).collect();
        assert_eq!(names.join("|"), Convention::NAMES);
    }

    /// A pose measured under a mistaken convention is re-read as the standard frame's.
    #[test]
    fn each_mistake_is_undone() {
        let truth = Measurement {
            x_m: 0.04,
            y_m: -0.03,
            theta_rad: Some(0.1),
        };
        let typed = |c: Convention| match c {
            Convention::Standard => truth,
            Convention::YRight => Measurement {
                y_m: 0.03,
                theta_rad: Some(-0.1),
                ..truth
            },
            Convention::Swapped => Measurement {
                x_m: -0.03,
                y_m: 0.04,
                ..truth
            },
            Convention::HeadingSign => Measurement {
                theta_rad: Some(-0.1),
                ..truth
            },
            // 0.1 typed as degrees: 0.1 × π/180 rad stored.
            Convention::ThetaRadians => Measurement {
                theta_rad: Some(0.1_f64.to_radians()),
                ..truth
            },
            // 5.729… typed as radians.
            Convention::ThetaDegrees => Measurement {
                theta_rad: Some(0.1_f64.to_degrees()),
                ..truth
            },
        };
        for c in Convention::ALL {
            let back = c.reread(typed(c));
            assert!((back.x_m - truth.x_m).abs() < 1e-15, "{c:?}");
            assert!((back.y_m - truth.y_m).abs() < 1e-15, "{c:?}");
            assert!((back.theta_rad.unwrap() - 0.1).abs() < 1e-12, "{c:?}");
        }
    }
}
