//! The motor outputs' safe state for a board whose TIM1 PWM pins and bridge enable share one GPIO
//! port (the register work of a board's `safety` module; the board names the port and pins).
//!
//! Safe means: the PWM pins and the bridge enable are push-pull outputs driven low, with
//! pull-downs (out of reset they are floating inputs, which some bridges read as "enabled"); in
//! an emergency also TIM1's main output off with its automatic re-enable cleared (BDTR.MOE and
//! BDTR.AOE: the HAL's PWM sets AOE, which would set MOE again at the next update) and both
//! compare values zero.

use stm32f4xx_hal::pac::{self, gpioa::RegisterBlock};

/// GPIO register values for `pins`: (BSRR word that drives them low, MODER/PUPDR mask of their
/// bit pairs, MODER bits making them outputs, PUPDR bits giving them pull-downs).
pub const fn pin_fields(pins: &[u32]) -> (u32, u32, u32, u32) {
    let (mut low, mut mask2, mut output, mut pull_down) = (0u32, 0u32, 0u32, 0u32);
    let mut i = 0;
    while i < pins.len() {
        let pin = pins[i];
        low |= 1 << (pin + 16);
        mask2 |= 0b11 << (2 * pin);
        output |= 0b01 << (2 * pin);
        pull_down |= 0b10 << (2 * pin);
        i += 1;
    }
    (low, mask2, output, pull_down)
}

/// Drives `pins` of `port` low as outputs with pull-downs.
///
/// # Safety
/// `port` is a GPIO port's register block whose clock is on, owned by the caller (nothing else
/// writes it meanwhile); only the bit pairs of `pins` change.
pub unsafe fn drive_safe(port: *const RegisterBlock, pins: &[u32]) {
    let (low, mask2, output, pull_down) = pin_fields(pins);
    // SAFETY: the caller's promise above; BSRR resets only these pins, and the MODER/PUPDR
    // read-modify-writes change only their bit pairs.
    unsafe {
        let port = &*port;
        port.bsrr().write(|w| w.bits(low));
        port.pupdr()
            .modify(|r, w| w.bits((r.bits() & !mask2) | pull_down));
        port.moder()
            .modify(|r, w| w.bits((r.bits() & !mask2) | output));
    }
}

/// TIM1_BDTR.MOE: main output enable.
const BDTR_MOE: u32 = 1 << 15;
/// TIM1_BDTR.AOE: automatic output enable (MOE set again at the next update event).
const BDTR_AOE: u32 = 1 << 14;

/// Motors off from any context: `pins` of `port` driven low as plain outputs, TIM1's main output
/// off, both compare values zero.
///
/// # Safety
/// Called only from the panic and HardFault handlers, which never return: the drivers that own
/// these registers never run again, so their read-modify-writes cannot be undone by an
/// interrupted one. With the port's or TIM1's clock still off (a fault early in `init`) the
/// writes are ignored and the pins are still in their reset state.
pub unsafe fn emergency_stop(port: *const RegisterBlock, pins: &[u32]) {
    let (low, mask2, output, _) = pin_fields(pins);
    // SAFETY: the caller's promise above. BSRR is a write-only set/reset register (the write
    // drives only `pins` low), MODER changes only their bit pairs (AF → output), the BDTR write
    // clears only MOE and AOE, and CCR1/CCR2 become 0.
    unsafe {
        let port = &*port;
        port.bsrr().write(|w| w.bits(low));
        port.moder()
            .modify(|r, w| w.bits((r.bits() & !mask2) | output));
        let tim1 = &*pac::TIM1::ptr();
        tim1.bdtr()
            .modify(|r, w| w.bits(r.bits() & !(BDTR_MOE | BDTR_AOE)));
        tim1.ccr1().write(|w| w.bits(0));
        tim1.ccr2().write(|w| w.bits(0));
    }
}

/// RCC_AHB1ENR's address (the GPIO ports' clock enables; the same on the three parts).
pub const RCC_AHB1ENR: u32 = 0x4002_3830;
/// GPIO port A's address; port `n` is at `GPIO_BASE + n * GPIO_STRIDE`.
pub const GPIO_BASE: u32 = 0x4002_0000;
/// The distance between two GPIO ports' register blocks.
pub const GPIO_STRIDE: u32 = 0x400;

/// A board's motor-pin functions for TIM1 PWM and bridge enable pins on one GPIO port:
/// `__pre_init` (the motor pins safe before RAM is initialised), `motor_port_without_reset`
/// (the port's pin tokens without the HAL's `split`, which would reset the port and leave the
/// motor pins floating, pull-downs cleared, until their drivers take them) and
/// `odocal_emergency_stop` (from the panic and HardFault handlers; never inlined and with a
/// fixed symbol name, so the firmware-in-the-loop check can see the handlers call it first).
///
/// `motor_safety!(GPIOA, gpioa, 0, [8, 9, 10])`: the port, its HAL module, its index (A = 0,
/// its RCC_AHB1ENR bit), and the pins (the PWM pins and the bridge enable).
macro_rules! motor_safety {
    ($port:ident, $module:ident, $index:literal, $pins:expr) => {
        /// The PWM and bridge-enable pins of the motor port.
        pub const MOTOR_PINS: [u32; 3] = $pins;

        // The motor pins safe before anything else runs: cortex-m-rt's reset handler calls
        // `__pre_init` before it zeroes .bss and copies .data (about 0.3 ms at the reset
        // clock, docs/hardware.md), so it is assembly that uses registers only (no stack, no RAM): the port's clock on
        // (RCC_AHB1ENR, read back: two AHB cycles before the port responds), then BSRR drives
        // the pins low, PUPDR gives them pull-downs and MODER makes them outputs
        // (read-modify-writes of their bit pairs only). docs/hardware.md states the window
        // that remains, measured in QEMU.
        core::arch::global_asm!(
            ".pushsection .text.__pre_init,\"ax\",%progbits",
            ".global __pre_init",
            ".type __pre_init,%function",
            ".thumb_func",
            "__pre_init:",
            "ldr r0, ={ahb1enr}",
            "ldr r1, [r0]",
            "orr r1, r1, #{enable}",
            "str r1, [r0]",
            "ldr r1, [r0]",
            "ldr r0, ={port}",
            "ldr r1, ={low}",
            "str r1, [r0, #0x18]",
            "ldr r2, ={mask}",
            "ldr r1, [r0, #0x0c]",
            "bics r1, r2",
            "ldr r3, ={pull_down}",
            "orrs r1, r3",
            "str r1, [r0, #0x0c]",
            "ldr r1, [r0]",
            "bics r1, r2",
            "ldr r3, ={output}",
            "orrs r1, r3",
            "str r1, [r0]",
            "bx lr",
            ".ltorg",
            ".size __pre_init, . - __pre_init",
            ".popsection",
            ahb1enr = const $crate::board::stm32f4::safe_state::RCC_AHB1ENR,
            enable = const 1u32 << $index,
            port = const $crate::board::stm32f4::safe_state::GPIO_BASE
                + $index * $crate::board::stm32f4::safe_state::GPIO_STRIDE,
            low = const $crate::board::stm32f4::safe_state::pin_fields(&$pins).0,
            mask = const $crate::board::stm32f4::safe_state::pin_fields(&$pins).1,
            output = const $crate::board::stm32f4::safe_state::pin_fields(&$pins).2,
            pull_down = const $crate::board::stm32f4::safe_state::pin_fields(&$pins).3,
        );

        /// The motor port's pin tokens without the HAL's `split`, which would reset the whole
        /// port (RCC_AHB1RSTR) and leave the motor pins floating, pull-downs cleared, until their
        /// drivers take them. Here they keep the state `__pre_init` gave them (which also
        /// enabled the port's clock); the HAL's mode changes then set each pin's mode, type
        /// and alternate function and never touch PUPDR, so the pull-downs stay on. The other
        /// pins of the port are as the chip's reset left them. `fil/safe_boot_test.py` lists
        /// every write to the port during the shipped image's boot and rejects a port reset.
        pub fn motor_port_without_reset(
            port: stm32f4xx_hal::pac::$port,
        ) -> stm32f4xx_hal::gpio::$module::Parts {
            const {
                assert!(core::mem::size_of::<stm32f4xx_hal::gpio::$module::Parts>() == 0);
            };
            // The port's only handle: no other pin tokens of the port can be made after this.
            let _ = port;
            // SAFETY: `Parts` is zero-sized (a zero-sized token per pin, checked above): no
            // bytes are made up. `port`, consumed here, was the only way to get the port's
            // tokens, so these are the only ones, as `split` would have returned them.
            unsafe { core::mem::zeroed() }
        }

        /// Motors off from any context (panic, HardFault).
        #[inline(never)]
        #[unsafe(no_mangle)]
        pub extern "C" fn odocal_emergency_stop() {
            // SAFETY: called only from the fault handlers, which never return.
            unsafe {
                $crate::board::stm32f4::safe_state::emergency_stop(
                    stm32f4xx_hal::pac::$port::ptr().cast(),
                    &MOTOR_PINS,
                )
            };
        }
    };
}
pub(crate) use motor_safety;
