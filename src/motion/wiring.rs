//! Wiring corrections: a motor or an encoder connected the other way round than the board's
//! standard wiring.
//!
//! The standard wiring already accounts for the mirrored left side (its motor direction and its
//! encoder count are inverted by the board and the encoder defaults). A [`Wiring`] flips what is
//! connected differently on a particular robot: a swapped pair of motor leads reverses that
//! motor, a swapped A/B pair reverses that encoder. The operator finds them with the bring-up
//! check ([`crate::motion::bringup`]) and stores them with the other parameters; a wrong sign
//! is otherwise caught by the following-error fault, never by a runaway.

use crate::motion::wheel::Wheel;

/// Which motors and encoders are reversed against the standard wiring.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Wiring {
    /// The right motor turns backward for a forward duty.
    pub motor_right_reversed: bool,
    /// The left motor turns backward for a forward duty.
    pub motor_left_reversed: bool,
    /// The right encoder counts backward when its wheel rolls forward.
    pub encoder_right_reversed: bool,
    /// The left encoder counts backward when its wheel rolls forward.
    pub encoder_left_reversed: bool,
}

impl Wiring {
    /// The board's standard wiring: nothing reversed.
    pub const STANDARD: Wiring = Wiring {
        motor_right_reversed: false,
        motor_left_reversed: false,
        encoder_right_reversed: false,
        encoder_left_reversed: false,
    };

    /// Sign applied to a wheel's duty before it reaches the motor driver (±1).
    pub fn motor_sign(&self, wheel: Wheel) -> f32 {
        let reversed = match wheel {
            Wheel::Right => self.motor_right_reversed,
            Wheel::Left => self.motor_left_reversed,
        };
        if reversed { -1.0 } else { 1.0 }
    }

    /// Whether a wheel's encoder is reversed.
    pub fn encoder_reversed(&self, wheel: Wheel) -> bool {
        match wheel {
            Wheel::Right => self.encoder_right_reversed,
            Wheel::Left => self.encoder_left_reversed,
        }
    }

    /// The four flags as bits (motor right, motor left, encoder right, encoder left = bits 0–3),
    /// the stored form.
    pub fn to_bits(self) -> u8 {
        u8::from(self.motor_right_reversed)
            | u8::from(self.motor_left_reversed) << 1
            | u8::from(self.encoder_right_reversed) << 2
            | u8::from(self.encoder_left_reversed) << 3
    }

    /// The inverse of [`Wiring::to_bits`]; `None` when a bit above bit 3 is set.
    pub fn from_bits(bits: u8) -> Option<Wiring> {
        if bits & !0x0F != 0 {
            return None;
        }
        Some(Wiring {
            motor_right_reversed: bits & 1 != 0,
            motor_left_reversed: bits & 2 != 0,
            encoder_right_reversed: bits & 4 != 0,
            encoder_left_reversed: bits & 8 != 0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_round_trip_and_reject_unknown_bits() {
        for bits in 0..16u8 {
            assert_eq!(Wiring::from_bits(bits).unwrap().to_bits(), bits);
        }
        assert_eq!(Wiring::from_bits(0x10), None);
        assert_eq!(Wiring::default(), Wiring::STANDARD);
        let w = Wiring::from_bits(0b0110).unwrap();
        assert_eq!(w.motor_sign(Wheel::Right), 1.0);
        assert_eq!(w.motor_sign(Wheel::Left), -1.0);
        assert!(w.encoder_reversed(Wheel::Right));
        assert!(!w.encoder_reversed(Wheel::Left));
    }
}
