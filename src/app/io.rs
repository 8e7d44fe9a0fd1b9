//! The board's LEDs, button and console port in embedded-hal 1.0 terms.
//!
//! A board hands the app core its pins and serial port as the standard traits: the LEDs as
//! [`OutputPin`]s (the heartbeat a [`StatefulOutputPin`], so it can toggle), the button as an
//! [`InputPin`], the console's receiver as an `embedded-hal-nb` serial reader and its transmitter
//! as an `embedded-io` writer. A new board is then its pin map and its interrupt
//! acknowledgements, not a rewrite of the glue.
//!
//! Pin errors are `Infallible` on every MCU GPIO; a pin that can fail (an I/O expander) fails
//! safe: an LED write that fails is dropped (a status light, nothing depends on it), and a
//! button read that fails reads as released (a failure never invents a press).

use embedded_hal::digital::{InputPin, OutputPin, PinState, StatefulOutputPin};
use embedded_hal_nb::serial;

use crate::protocol::rx::RxRead;

/// The heartbeat and fault LEDs.
#[derive(Debug)]
pub struct Leds<H, F> {
    heartbeat: H,
    fault: F,
}

impl<H: StatefulOutputPin, F: OutputPin> Leds<H, F> {
    /// The two LED outputs.
    pub const fn new(heartbeat: H, fault: F) -> Self {
        Leds { heartbeat, fault }
    }

    /// Toggles the heartbeat LED.
    pub fn toggle_heartbeat(&mut self) {
        // A status light: a failed write is dropped (module docs).
        let _ = self.heartbeat.toggle();
    }

    /// Lights the fault LED while `on`.
    pub fn set_fault(&mut self, on: bool) {
        let _ = self.fault.set_state(PinState::from(on));
    }
}

/// The button's level: `true` while pressed (`active_high` says which level that is). A read
/// that fails is released.
pub fn button_pressed(pin: &mut impl InputPin, active_high: bool) -> bool {
    match pin.is_high() {
        Ok(high) => high == active_high,
        Err(_) => false,
    }
}

/// One read of the console's receiver: a byte, nothing, or a receive error (overrun, framing,
/// noise, parity; the reader clears the error's flag, and the line being received is poisoned).
pub fn read_console(rx: &mut impl serial::Read<u8>) -> RxRead {
    match rx.read() {
        Ok(byte) => RxRead::Byte(byte),
        Err(nb::Error::WouldBlock) => RxRead::Empty,
        Err(nb::Error::Other(_)) => RxRead::Error,
    }
}

/// Writes one byte to the console's transmitter, which the caller has seen ready (its data
/// register empty), so the write cannot block. Returns whether the byte went out.
pub fn write_console(tx: &mut impl embedded_io::Write, byte: u8) -> bool {
    matches!(tx.write(&[byte]), Ok(1))
}

#[cfg(test)]
mod tests {
    use core::convert::Infallible;

    use super::*;

    #[derive(Default)]
    struct Pin {
        high: bool,
        writes: u32,
    }

    impl embedded_hal::digital::ErrorType for Pin {
        type Error = Infallible;
    }

    impl OutputPin for Pin {
        fn set_low(&mut self) -> Result<(), Infallible> {
            self.high = false;
            self.writes += 1;
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            self.high = true;
            self.writes += 1;
            Ok(())
        }
    }

    impl StatefulOutputPin for Pin {
        fn is_set_high(&mut self) -> Result<bool, Infallible> {
            Ok(self.high)
        }
        fn is_set_low(&mut self) -> Result<bool, Infallible> {
            Ok(!self.high)
        }
    }

    impl InputPin for Pin {
        fn is_high(&mut self) -> Result<bool, Infallible> {
            Ok(self.high)
        }
        fn is_low(&mut self) -> Result<bool, Infallible> {
            Ok(!self.high)
        }
    }

    /// An input behind a bus that has failed.
    struct BrokenPin;

    #[derive(Debug)]
    struct BusError;

    impl embedded_hal::digital::Error for BusError {
        fn kind(&self) -> embedded_hal::digital::ErrorKind {
            embedded_hal::digital::ErrorKind::Other
        }
    }

    impl embedded_hal::digital::ErrorType for BrokenPin {
        type Error = BusError;
    }

    impl InputPin for BrokenPin {
        fn is_high(&mut self) -> Result<bool, BusError> {
            Err(BusError)
        }
        fn is_low(&mut self) -> Result<bool, BusError> {
            Err(BusError)
        }
    }

    #[test]
    fn the_heartbeat_toggles_and_the_fault_led_follows_the_fault() {
        let mut leds = Leds::new(Pin::default(), Pin::default());
        leds.toggle_heartbeat();
        assert!(leds.heartbeat.high);
        leds.toggle_heartbeat();
        assert!(!leds.heartbeat.high);
        leds.set_fault(true);
        assert!(leds.fault.high);
        leds.set_fault(false);
        assert!(!leds.fault.high);
        assert_eq!((leds.heartbeat.writes, leds.fault.writes), (2, 2));
    }

    #[test]
    fn the_button_reads_its_active_level_and_a_failed_read_is_released() {
        let mut pin = Pin {
            high: true,
            writes: 0,
        };
        assert!(button_pressed(&mut pin, true));
        assert!(!button_pressed(&mut pin, false));
        pin.high = false;
        assert!(!button_pressed(&mut pin, true));
        assert!(button_pressed(&mut pin, false));
        assert!(!button_pressed(&mut BrokenPin, true));
        assert!(!button_pressed(&mut BrokenPin, false));
    }

    /// A receiver that yields its script, one result per read.
    struct Script<'a>(&'a [Result<u8, nb::Error<serial::ErrorKind>>]);

    impl serial::ErrorType for Script<'_> {
        type Error = serial::ErrorKind;
    }

    impl serial::Read<u8> for Script<'_> {
        fn read(&mut self) -> nb::Result<u8, serial::ErrorKind> {
            let (first, rest) = self.0.split_first().ok_or(nb::Error::WouldBlock)?;
            self.0 = rest;
            *first
        }
    }

    #[test]
    fn a_receive_error_is_reported_as_one_and_the_bytes_around_it_arrive() {
        let script = [
            Ok(b'a'),
            Err(nb::Error::Other(serial::ErrorKind::Overrun)),
            Ok(b'b'),
        ];
        let mut rx = Script(&script);
        assert_eq!(read_console(&mut rx), RxRead::Byte(b'a'));
        assert_eq!(read_console(&mut rx), RxRead::Error);
        assert_eq!(read_console(&mut rx), RxRead::Byte(b'b'));
        assert_eq!(read_console(&mut rx), RxRead::Empty);
    }

    /// A transmitter with a one-byte data register.
    struct Register(Option<u8>);

    impl embedded_io::ErrorType for Register {
        type Error = Infallible;
    }

    impl embedded_io::Write for Register {
        fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
            match (self.0, buf.first()) {
                (None, Some(&b)) => {
                    self.0 = Some(b);
                    Ok(1)
                }
                _ => Ok(0),
            }
        }
        fn flush(&mut self) -> Result<(), Infallible> {
            Ok(())
        }
    }

    #[test]
    fn a_byte_goes_out_only_into_an_empty_register() {
        let mut tx = Register(None);
        assert!(write_console(&mut tx, b'x'));
        assert!(!write_console(&mut tx, b'y'));
        assert_eq!(tx.0, Some(b'x'));
    }
}
