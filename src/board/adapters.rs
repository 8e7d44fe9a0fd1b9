//! The board's peripherals and RTIC resources behind the portable traits the app core and the
//! session use: the console USART as [`TxPort`] and a receive read, an RTIC lock on the
//! controller as [`ControllerLock`], and the parameter store with the watchdog relaxed around
//! flash writes as [`SettingsAndRuns`].

use stm32f4xx_hal::serial::{TxISR, TxListen};
use stm32f4xx_hal::watchdog::IndependentWatchdog;

use super::watchdog::{wait_for_update, write_timeout};
use super::{BoardFlash, ConsoleRx, ConsoleTx, FLASH_WATCHDOG_MS, WATCHDOG_MS};
use crate::app::serial::TxPort;
use crate::motion::controller::{Controller, MotorsStopped};
use crate::motion::run::{MAX_RUNS, RunRecord};
use crate::protocol::rx::RxRead;
use crate::session::library::ControllerLock;
use crate::session::{Settings, SettingsAndRuns, StoreError};
use crate::storage::{ParamAndRunStore, RunsLoaded, StoredRun};

impl<M: rtic::Mutex<T = Controller>> ControllerLock for M {
    fn with_controller<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> R {
        self.lock(f)
    }
}

/// One read of the console's receiver (see [`crate::app::io::read_console`]). Each read
/// checks SR and, on an overrun, framing, noise or parity error, reads DR, which clears the flag
/// (an ORE with RXNE clear would otherwise re-enter the interrupt for ever).
pub fn read_console(rx: &mut ConsoleRx) -> RxRead {
    crate::app::io::read_console(rx)
}

impl TxPort for ConsoleTx {
    fn ready(&mut self) -> bool {
        self.is_tx_empty()
    }

    fn write(&mut self, byte: u8) {
        // Only called when the register is empty: the byte goes out.
        crate::app::io::write_console(self, byte);
    }

    fn interrupt_when_ready(&mut self, on: bool) {
        if on {
            self.listen();
        } else {
            self.unlisten();
        }
    }
}

/// Parameter storage with the watchdog relaxed while the flash is written: a sector erase
/// stalls every instruction fetch (the control task included) for up to 0.8 s (a parameter
/// sector) or 4 s (a run sector), so the timeout is
/// lengthened for the operation and restored right after. A save takes the controller's proof
/// that the motors are stopped, so nothing moves while the control task is stalled.
pub struct RelaxedWatchdog<'a, W: rtic::Mutex<T = IndependentWatchdog>> {
    /// The parameter and run store.
    pub store: &'a mut ParamAndRunStore<BoardFlash>,
    /// The watchdog, shared with the control task.
    pub watchdog: W,
}

impl<W: rtic::Mutex<T = IndependentWatchdog>> RelaxedWatchdog<'_, W> {
    // Out of line: inlined into the session's command dispatch, the parameter save alone cost
    // about 0.8 KiB more flash.
    #[inline(never)]
    fn relaxed<R>(&mut self, f: impl FnOnce(&mut ParamAndRunStore<BoardFlash>) -> R) -> R {
        self.set_timeout(FLASH_WATCHDOG_MS);
        let result = f(self.store);
        self.set_timeout(WATCHDOG_MS);
        result
    }

    /// Sets the watchdog's timeout and feeds it: wait, write, wait, reload, the sequence of
    /// [`super::watchdog::set_timeout`] with the waits outside the lock. Out of line: each store
    /// operation's [`Self::relaxed`] would otherwise carry both changes.
    #[inline(never)]
    fn set_timeout(&mut self, timeout_ms: u32) {
        // The waits for the low-power register domain stay outside the lock, so the control
        // task is never held up by them (the first finds nothing pending when the timeout goes
        // back after a store operation). The reload comes after the update has crossed over:
        // an earlier one would load the old 50 ms reload value, counted at the new divider
        // (about 1.1-1.6 s, shorter than an erase).
        wait_for_update();
        self.watchdog.lock(|w| write_timeout(w, timeout_ms));
        wait_for_update();
        self.watchdog.lock(|w| w.feed());
    }
}

impl<W: rtic::Mutex<T = IndependentWatchdog>> SettingsAndRuns for RelaxedWatchdog<'_, W> {
    fn usable(&self) -> Result<(), StoreError> {
        self.store.usable()
    }

    fn save(&mut self, settings: &Settings, stopped: MotorsStopped) -> Result<(), StoreError> {
        self.relaxed(|s| SettingsAndRuns::save(s, settings, stopped))
    }

    fn save_runs(
        &mut self,
        runs: &[RunRecord],
        ids: &mut [Option<StoredRun>],
        stopped: MotorsStopped,
    ) -> Result<(), StoreError> {
        self.relaxed(|s| SettingsAndRuns::save_runs(s, runs, ids, stopped))
    }

    fn load_runs(
        &mut self,
        runs: &mut heapless::Vec<RunRecord, MAX_RUNS>,
        ids: &mut heapless::Vec<Option<StoredRun>, MAX_RUNS>,
    ) -> RunsLoaded {
        // Only at boot, motors stopped: a repair may erase a sector.
        self.relaxed(|s| SettingsAndRuns::load_runs(s, runs, ids))
    }
}
