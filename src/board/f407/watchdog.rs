//! Independent watchdog (IWDG) timeout changes that follow the register-update protocol.
//!
//! The IWDG's prescaler and reload registers live in the low-power domain: after a write the
//! hardware sets `PVU`/`RVU` in `IWDG_SR` until the value has crossed over (up to 5 cycles of the
//! ~32 kHz LSI, about 150 µs), and a second write before then may be lost (RM0090 §21.4). The HAL's
//! `start` does not wait, so a timeout changed twice in quick succession could stay at the first
//! value. [`set_timeout`] waits before and after the change.

use stm32f4xx_hal::pac::IWDG;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::watchdog::IndependentWatchdog;

/// Waits until no prescaler or reload update is pending (at most about 150 µs).
pub fn wait_for_update() {
    // SAFETY: a read of IWDG_SR, a read-only status register without side effects; the
    // watchdog itself stays owned by the `IndependentWatchdog` driver.
    let iwdg = unsafe { &*IWDG::ptr() };
    while iwdg.sr().read().bits() != 0 {}
}

/// Sets the watchdog timeout to `ms` milliseconds and reloads the counter. Call
/// [`wait_for_update`] before (and before the next change); it is kept outside so a caller can
/// wait without holding the watchdog's lock.
pub fn start_with_timeout(watchdog: &mut IndependentWatchdog, ms: u32) {
    watchdog.start(ms.millis());
    watchdog.feed();
}

/// [`wait_for_update`], [`start_with_timeout`], [`wait_for_update`].
pub fn set_timeout(watchdog: &mut IndependentWatchdog, ms: u32) {
    wait_for_update();
    start_with_timeout(watchdog, ms);
    wait_for_update();
}
