//! Independent watchdog (IWDG) timeout changes that follow the register-update protocol.
//!
//! The IWDG's prescaler and reload registers live in the low-power domain: after a write the
//! hardware sets `PVU`/`RVU` in `IWDG_SR` until the value has crossed over (up to 5 cycles of the
//! ~32 kHz LSI, about 150 µs), and a second write before then may be lost (RM0090 §21.4). A
//! reload (key 0xAAAA) while the update is still pending loads the counter with the *previous*
//! reload value, now counted at the new prescaler: going from 50 ms (divider 4, reload 399) to
//! 10 s (divider 128, reload 2499), a reload right after the writes leaves the counter at 399
//! ticks of the new divider, about 1.1–1.6 s, which a sector erase (2–4 s) outlasts. So a change
//! is: wait, write ([`write_timeout`]), wait, reload — the order of ST's own driver
//! (`HAL_IWDG_Init`). The HAL's `start` reloads without waiting. [`set_timeout`] does the whole
//! sequence; the app does it step by step so that it holds the watchdog's lock only for the
//! register writes.

use stm32f4xx_hal::pac::IWDG;
use stm32f4xx_hal::watchdog::IndependentWatchdog;

/// Waits until no prescaler or reload update is pending (at most about 150 µs).
pub fn wait_for_update() {
    // SAFETY: a read of IWDG_SR, a read-only status register without side effects; the
    // watchdog itself stays owned by the `IndependentWatchdog` driver.
    let iwdg = unsafe { &*IWDG::ptr() };
    while iwdg.sr().read().bits() != 0 {}
}

/// Nominal LSI frequency the timeouts are computed for, Hz (RM0090: 17–47 kHz over the
/// temperature and supply range; 32 kHz typical).
pub const LSI_HZ: u32 = 32_000;

/// Prescaler code (`IWDG_PR`, divider 4 << code) and reload value (`IWDG_RLR`, 12 bits) for a
/// timeout of `ms` milliseconds at [`LSI_HZ`]: the smallest divider whose 12-bit reload reaches
/// `ms`, which is also the finest resolution. 50 ms → divider 4, reload 399 (exactly 50.0 ms);
/// 10 s → divider 128, reload 2499 (exactly 10.0 s). The HAL's own choice gave 56 ms for 50.
pub const fn divider_and_reload(ms: u32) -> (u8, u16) {
    let mut code = 0u8;
    while code < 6 {
        let div = 4u64 << code;
        let ticks = (ms as u64 * LSI_HZ as u64).div_ceil(1000 * div);
        if ticks <= 4096 {
            let reload = if ticks == 0 { 0 } else { ticks - 1 };
            return (code, reload as u16);
        }
        code += 1;
    }
    let ticks = (ms as u64 * LSI_HZ as u64).div_ceil(1000 * 256);
    let reload = if ticks > 4096 {
        4095
    } else {
        ticks.saturating_sub(1)
    };
    (6, reload as u16)
}

const _: () = {
    let (code, reload) = divider_and_reload(50);
    assert!(code == 0 && reload == 399, "50 ms must be exact");
    let (code, reload) = divider_and_reload(10_000);
    assert!(code == 5 && reload == 2499, "10 s must be exact");
};

/// Writes the prescaler and reload for a timeout of `ms` milliseconds ([`divider_and_reload`])
/// and starts the watchdog if it is not running. Does **not** reload the counter: call
/// [`wait_for_update`] before (and before the next change), then [`wait_for_update`] again and
/// feed, so the counter is loaded with the new reload value (see the module docs). The waits are
/// kept outside so a caller can wait without holding the watchdog's lock. `_watchdog` is the
/// HAL's handle: owning it is what allows the change.
pub fn write_timeout(_watchdog: &mut IndependentWatchdog, ms: u32) {
    let (code, reload) = divider_and_reload(ms);
    // SAFETY: IWDG register writes in the order RM0090 §21.3.2 gives (unlock with 0x5555,
    // prescaler, reload; start with 0xCCCC, which does nothing to a running watchdog); the
    // caller holds the only handle, so nothing else writes these registers meanwhile.
    unsafe {
        let iwdg = &*IWDG::ptr();
        iwdg.kr().write(|w| w.bits(0x5555));
        iwdg.pr().write(|w| w.bits(u16::from(code)));
        iwdg.rlr().write(|w| w.bits(reload));
        iwdg.kr().write(|w| w.bits(0xCCCC));
    }
}

/// Sets the timeout to `ms` milliseconds and starts the watchdog if needed: [`wait_for_update`],
/// [`write_timeout`], [`wait_for_update`], then a reload, which loads the new value.
pub fn set_timeout(watchdog: &mut IndependentWatchdog, ms: u32) {
    wait_for_update();
    write_timeout(watchdog, ms);
    wait_for_update();
    watchdog.feed();
}
