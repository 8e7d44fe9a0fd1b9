//! The QEMU side of the benchmark (netduinoplus2, Cortex-M4F, semihosting output).
//!
//! Instruction counts come from the `insnwin` TCG plugin: it counts every executed guest
//! instruction and attributes the count between a call of [`bench_start`] and the next call of
//! [`bench_end`] to the window chosen by the last `bench_select_*` call. A window therefore
//! also contains the marker call overhead (measured by the `empty` window, which `run.sh`
//! subtracts). The SysTick block is an independent cross-check that needs no plugin: under
//! `-icount shift=0` one instruction takes 1 ns of virtual time and the netduinoplus2 SysTick
//! runs at 168 MHz.
//!
//! The stack is painted with a pattern from `_stack_end` (the lowest address the stack may
//! reach) up to the current stack pointer before each workload and scanned afterwards; the
//! high-water mark is the distance from `_stack_start` to the lowest overwritten word, so it
//! includes `main`'s own frames.

use core::arch::asm;
use core::fmt::Write;
use core::hint::black_box;
use core::ptr::{addr_of, addr_of_mut};

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{ExceptionFrame, entry, exception};
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use cortex_m_semihosting::hio;
use odocal::app::Handoff;
use odocal::calibration::{Calibration, CalibrationError, Method, RunObservation, calibrate};
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::odometry::{Integration, Odometry, OdometryState, Pose};
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::bringup::CheckReport;
use odocal::motion::controller::{Controller, StepOutput};
use odocal::session::library::LockedController;
use qemu_bench::console;
use qemu_bench::control::{self, BenchRobot};
use qemu_bench::report;
use qemu_bench::squares::{self, SquareRuns};
use qemu_bench::trace::Trace;
// Interrupt vector table (see Cargo.toml).
use stm32f4xx_hal as _;

/// Steps of the SysTick cross-check block (about 3.5 M instructions: no 24-bit wrap).
const BLOCK_STEPS: u32 = 10_000;
/// Steps integrated with the midpoint rule (a shorter second run).
const MIDPOINT_STEPS: u32 = 100_000;
/// Repetitions of the empty window.
const EMPTY_WINDOWS: u32 = 1_000;
/// Stack paint pattern.
const PAINT: u32 = 0xA5A5_A5A5;

unsafe extern "C" {
    /// Lowest address the stack may grow to (flip-link: ORIGIN(RAM)).
    static mut _stack_end: u32;
    /// Initial stack pointer (flip-link: just below .data).
    static _stack_start: u32;
    /// Defined only by the bench's memory.x (proves which memory.x was linked); after flip-link's
    /// relink, the start of RAM above the stack.
    static _qemu_bench_layout: u8;
}

/// Start of a counted window.
#[unsafe(no_mangle)]
#[inline(never)]
pub extern "C" fn bench_start() {
    // SAFETY: a no-op instruction; the asm has no outputs and may be treated as touching
    // memory, which keeps the compiler from moving work across the marker.
    unsafe { asm!("nop") }
}

/// End of a counted window.
#[unsafe(no_mangle)]
#[inline(never)]
pub extern "C" fn bench_end() {
    // SAFETY: as in `bench_start`; two nops keep the two markers at different addresses.
    unsafe { asm!("nop", "nop") }
}

/// Generates a selector marker with `n` nops (distinct bodies, distinct addresses).
macro_rules! selector {
    ($name:ident, $n:literal) => {
        /// Selects the window the following `bench_start`/`bench_end` pairs are counted in.
        #[unsafe(no_mangle)]
        #[inline(never)]
        pub extern "C" fn $name() {
            // SAFETY: no-op instructions only, as in `bench_start`.
            unsafe { asm!(".rept {n}", "nop", ".endr", n = const $n) }
        }
    };
}

selector!(bench_select_empty, 3);
selector!(bench_select_block, 4);
selector!(bench_select_odometry, 5);
selector!(bench_select_midpoint, 6);
selector!(bench_select_solve, 7);
selector!(bench_select_arc_run, 8);
selector!(bench_select_control, 9);
selector!(bench_select_calibrate, 10);
selector!(bench_select_apply, 11);
selector!(bench_select_identify, 12);
selector!(bench_select_id_report, 13);
selector!(bench_select_period, 14);
selector!(bench_select_lock, 15);
selector!(bench_select_lock_idle, 16);

/// One control period of odometry, as the firmware's control task performs it.
#[inline(never)]
fn odometry_step(odo: &Odometry, state: &mut OdometryState, totals: WheelTicks) -> Pose {
    odo.update(state, totals)
}

/// Bytes left unpainted just below the stack pointer: this function's own frame (it saves
/// registers after reading SP). The high-water mark can therefore read at most this much high
/// for a workload that stays shallower than the caller's frame plus this margin.
const PAINT_MARGIN: usize = 64;

/// The exact calibration of the recorded squares, as the firmware's `calibrate` command runs it.
#[inline(never)]
fn exact_solve(
    runs: &[RunObservation<'_>],
    nominal: &Geometry,
) -> Result<Calibration, CalibrationError> {
    calibrate(runs, nominal, Method::Exact)
}

/// The controller's own step: encoders, odometry, routine, speed loops (the `control step`
/// line, the same window as the figures before the app core).
#[inline(never)]
fn controller_step(controller: &mut Controller, raw_right: u32, raw_left: u32) -> StepOutput {
    controller.step(raw_right, raw_left)
}

/// One period of the control task as the app core runs it (`app::control::period`, `TIM7`'s
/// work): stop request, encoders, odometry, routine, speed loops, the motor command.
#[inline(never)]
fn control_step(
    handoff: &Handoff,
    controller: &mut Controller,
    raw_right: u32,
    raw_left: u32,
    robot: &mut BenchRobot,
) -> StepOutput {
    control::period(handoff, controller, raw_right, raw_left, robot)
}

/// The console task's collection of a finished check's report (`Session::poll`).
#[inline(never)]
fn take_report(controller: &mut Controller) -> Option<CheckReport> {
    controller.take_check_report()
}

/// Paints the free stack below the current stack pointer; returns the stack depth of the
/// caller (bytes from `_stack_start` to the stack pointer at the call).
#[inline(never)]
fn paint_stack() -> usize {
    let sp = cortex_m::register::msp::read() as usize;
    let limit = sp - PAINT_MARGIN;
    // SAFETY: `_stack_end .. limit` is unused stack (nothing below the stack pointer is live and
    // no interrupt is enabled); the writes stay inside RAM and are word aligned (cortex-m-rt
    // asserts `_stack_end % 4 == 0`).
    unsafe {
        let mut p = addr_of_mut!(_stack_end);
        while (p as usize) < limit {
            p.write_volatile(PAINT);
            p = p.add(1);
        }
    }
    addr_of!(_stack_start) as usize - sp
}

/// Stack high-water mark since the last [`paint_stack`], bytes below `_stack_start`.
#[inline(never)]
fn stack_used() -> usize {
    // SAFETY: reads words of the stack region `_stack_end .. _stack_start`, all in RAM.
    unsafe {
        let top = addr_of!(_stack_start) as usize;
        let mut p = addr_of_mut!(_stack_end) as *const u32;
        while (p as usize) < top && p.read_volatile() == PAINT {
            p = p.add(1);
        }
        top - p as usize
    }
}

/// Integrates `trace` with one counted window per step; returns the final pose.
fn run_windows(odo: &Odometry, state: &mut OdometryState, trace: Trace) -> Pose {
    let mut pose = state.pose();
    for totals in trace {
        let totals = black_box(totals);
        bench_start();
        pose = odometry_step(black_box(odo), state, totals);
        bench_end();
        black_box(&pose);
    }
    pose
}

/// Prints one line; a host that has gone away cannot be reported to, so errors are ignored.
fn out(args: core::fmt::Arguments<'_>) {
    if let Ok(mut stdout) = hio::hstdout() {
        let _ = stdout.write_fmt(args);
    }
}

fn fail(what: &str) -> ! {
    out(format_args!("error {what}\n"));
    debug::exit(EXIT_FAILURE);
    loop {
        cortex_m::asm::bkpt();
    }
}

#[entry]
fn main() -> ! {
    let Some(cp) = cortex_m::Peripherals::take() else {
        fail("core peripherals taken twice")
    };
    let data = addr_of!(_qemu_bench_layout) as usize;
    let stack_bottom = addr_of!(_stack_end) as usize;
    let stack_top = addr_of!(_stack_start) as usize;
    out(format_args!(
        "info memory_layout stack=0x{stack_bottom:08x}..0x{stack_top:08x} data=0x{data:08x}\n"
    ));

    // Marker overhead: an empty window.
    bench_select_empty();
    for _ in 0..EMPTY_WINDOWS {
        bench_start();
        bench_end();
    }
    bench_systick(cp.SYST);
    bench_odometry();
    let runs = bench_calibration();
    bench_console(&runs);
    bench_console_locks(&runs);
    bench_control();
    bench_identify();

    out(format_args!("info done\n"));
    debug::exit(EXIT_SUCCESS);
    loop {
        cortex_m::asm::bkpt();
    }
}

/// SysTick cross-check: one window over a block of steps, trace generation included.
fn bench_systick(mut syst: SYST) {
    // SysTick cross-check: one window over a block of steps, trace generation included.
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(0x00FF_FFFF);
    syst.clear_current();
    syst.enable_counter();
    let Ok((odo, mut state)) = qemu_bench::odometry(Integration::ExactArc) else {
        fail("bench geometry rejected")
    };
    bench_select_block();
    let t0 = SYST::get_current();
    bench_start();
    for totals in Trace::with_steps(BLOCK_STEPS) {
        black_box(odometry_step(black_box(&odo), &mut state, totals));
    }
    bench_end();
    let t1 = SYST::get_current();
    let ticks = t0.wrapping_sub(t1) & 0x00FF_FFFF;
    out(format_args!(
        "info systick_block steps={BLOCK_STEPS} ticks={ticks}\n"
    ));
}

/// The standard trace with the exact-arc rule (the firmware's default), one window per step; a shorter run with the midpoint rule.
fn bench_odometry() {
    // The standard trace, exact-arc rule (the firmware's default), one window per step.
    let Ok((odo, mut state)) = qemu_bench::odometry(Integration::ExactArc) else {
        fail("bench geometry rejected")
    };
    let caller = paint_stack();
    bench_select_odometry();
    let pose = run_windows(&odo, &mut state, Trace::standard());
    let stack = stack_used();
    let mut line: heapless_line::Line = heapless_line::Line::new();
    let _ = report::pose_line(&mut line, "odometry_exact_arc", &pose);
    out(format_args!("{}", line.as_str()));
    out(format_args!(
        "info stack odometry high_water={stack} at_call={caller}\n"
    ));

    // A shorter run with the midpoint rule.
    let Ok((odo, mut state)) = qemu_bench::odometry(Integration::Midpoint) else {
        fail("bench geometry rejected")
    };
    bench_select_midpoint();
    let pose = run_windows(&odo, &mut state, Trace::with_steps(MIDPOINT_STEPS));
    let mut line = heapless_line::Line::new();
    let _ = report::pose_line(&mut line, "odometry_midpoint", &pose);
    out(format_args!("{}", line.as_str()));
}

/// The exact calibration of the recorded squares, and one re-integration of a run; the runs.
fn bench_calibration() -> SquareRuns {
    // The exact calibration of the recorded squares.
    let runs = SquareRuns::generate();
    let mut line = heapless_line::Line::new();
    let _ = report::bits_line(
        &mut line,
        "squares_fixture",
        &[("checksum", runs.checksum())],
    );
    out(format_args!("{}", line.as_str()));
    let observations = runs.observations();
    let nominal = squares::nominal();
    // One re-integration of a recorded run (what the solver repeats for every run and every
    // evaluation of its cost function).
    let model = ArcModel::from_geometry(&nominal);
    bench_select_arc_run();
    for o in &observations {
        let knots = black_box(o.knots);
        bench_start();
        let end = model.integrate(PoseF64::default(), knots);
        bench_end();
        black_box(end);
    }
    let caller = paint_stack();
    bench_select_solve();
    bench_start();
    let result = exact_solve(black_box(&observations), black_box(&nominal));
    bench_end();
    let stack = stack_used();
    let mut line = heapless_line::Line::new();
    let _ = report::calibration_line(&mut line, "solve_exact", &result);
    out(format_args!("{}", line.as_str()));
    out(format_args!(
        "info stack solve high_water={stack} at_call={caller}\n"
    ));

    runs
}

/// The console's `calibrate` and `apply exact` on the runs, as the console task runs them.
fn bench_console(runs: &SquareRuns) {
    // The console's `calibrate` and `apply exact` on the same runs, as the console task runs
    // them (the whole command: every method, the residual listing, the advice).
    let Ok(mut controller) = control::controller() else {
        fail("controller configuration rejected")
    };
    let mut robot = LockedController(&mut controller);
    let mut session = console::session(runs);
    let mut reply = console::ReplyHash::default();
    let caller = paint_stack();
    for (i, line) in console::COMMANDS.iter().enumerate() {
        if i == 0 {
            bench_select_calibrate();
        } else {
            bench_select_apply();
        }
        bench_start();
        console::command(black_box(&mut session), &mut robot, runs, line, &mut reply);
        bench_end();
    }
    let stack = stack_used();
    let mut line = heapless_line::Line::new();
    let _ = report::bits_line(
        &mut line,
        "console_calibrate_apply",
        &[
            ("reply_hash", reply.hash),
            ("reply_bytes", reply.bytes),
            (
                "exact_solves",
                u64::from(session.calibrator().exact_solves()),
            ),
        ],
    );
    out(format_args!("{}", line.as_str()));
    out(format_args!(
        "info stack console high_water={stack} at_call={caller}\n"
    ));
}

/// The console task's controller locks, one window per hold.
fn bench_console_locks(runs: &SquareRuns) {
    // The console task's controller locks (the firmware's `LockedController`): one window per hold over
    // a session touching every kind of access; the longest is the most a console command can
    // delay a control period.
    let Ok(mut controller) = control::controller() else {
        fail("controller configuration rejected")
    };
    let mut robot = LockedController(console::Bracketed {
        controller: &mut controller,
        open: || bench_start(),
        close: || bench_end(),
    });
    let mut session = console::session(runs);
    let mut reply = console::ReplyHash::default();
    for line in console::LOCK_SCRIPT {
        if console::changes_settings(line) {
            bench_select_lock_idle();
        } else {
            bench_select_lock();
        }
        console::command(black_box(&mut session), &mut robot, runs, line, &mut reply);
    }
    let mut line = heapless_line::Line::new();
    let _ = report::bits_line(
        &mut line,
        "console_locks",
        &[("reply_hash", reply.hash), ("reply_bytes", reply.bytes)],
    );
    out(format_args!("{}", line.as_str()));
}

/// The controller and the control task driving a 1 m square with the simulated robot.
fn bench_control() {
    // The controller driving a 1 m square with the simulated robot, one window per step (the
    // motor command's hand-off outside it).
    let Ok(mut controller) = control::controller() else {
        fail("controller configuration rejected")
    };
    bench_select_control();
    let driven = control::drive_square(&mut controller, |_, c, r, l, robot| {
        // The robot's counter values are materialised before the window opens: otherwise the
        // compiler may schedule the robot's arithmetic after `bench_start` and it would count
        // as the controller's.
        let (r, l) = (black_box(r), black_box(l));
        bench_start();
        let out = controller_step(black_box(c), r, l);
        bench_end();
        out.command.apply(robot);
        out
    });
    let (periods, record) = match driven {
        Ok(v) => v,
        Err(e) => fail(e),
    };
    let mut line = heapless_line::Line::new();
    let _ = report::run_line(&mut line, "control_square_step", periods, &record);
    out(format_args!("{}", line.as_str()));

    // The control task: the same square, one window per period of the app core.
    let Ok(mut controller) = control::controller() else {
        fail("controller configuration rejected")
    };
    let caller = paint_stack();
    bench_select_period();
    let driven = control::drive_square(&mut controller, |h, c, r, l, robot| {
        let (r, l) = (black_box(r), black_box(l));
        bench_start();
        let out = control_step(black_box(h), black_box(c), r, l, robot);
        bench_end();
        out
    });
    let stack = stack_used();
    let (periods, record) = match driven {
        Ok(v) => v,
        Err(e) => fail(e),
    };
    let mut line = heapless_line::Line::new();
    let _ = report::run_line(&mut line, "control_square", periods, &record);
    out(format_args!("{}", line.as_str()));
    out(format_args!(
        "info stack control high_water={stack} at_call={caller}\n"
    ));
}

/// The control task during a motor identification, and the console task's poll of its report.
fn bench_identify() {
    // The control task during a motor identification (wheels lifted, the robot's motors), one
    // window per period, and the console task's poll of the report after each period.
    let Ok(mut controller) = control::controller() else {
        fail("controller configuration rejected")
    };
    let caller = paint_stack();
    let identified = control::identify(
        &mut controller,
        |h, c, r, l, robot| {
            let (r, l) = (black_box(r), black_box(l));
            bench_select_identify();
            bench_start();
            let out = control_step(black_box(h), black_box(c), r, l, robot);
            bench_end();
            out
        },
        |c| {
            bench_select_id_report();
            bench_start();
            let report = take_report(black_box(c));
            bench_end();
            report
        },
    );
    let stack = stack_used();
    let (periods, report) = match identified {
        Ok(v) => v,
        Err(e) => fail(e),
    };
    let mut line = heapless_line::Line::new();
    let _ = report::identify_line(&mut line, "identify_lifted", periods, &report);
    out(format_args!("{}", line.as_str()));
    out(format_args!(
        "info stack identify high_water={stack} at_call={caller}\n"
    ));
}

/// A fixed-capacity line buffer, so that a result line reaches the host in one write.
mod heapless_line {
    /// Up to 256 bytes of text.
    pub struct Line {
        buf: [u8; 256],
        len: usize,
    }

    impl Line {
        pub const fn new() -> Self {
            Line {
                buf: [0; 256],
                len: 0,
            }
        }

        pub fn as_str(&self) -> &str {
            core::str::from_utf8(&self.buf[..self.len]).unwrap_or("<invalid utf-8>\n")
        }
    }

    impl core::fmt::Write for Line {
        fn write_str(&mut self, s: &str) -> core::fmt::Result {
            let end = self.len + s.len();
            if end > self.buf.len() {
                return Err(core::fmt::Error);
            }
            self.buf[self.len..end].copy_from_slice(s.as_bytes());
            self.len = end;
            Ok(())
        }
    }
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    out(format_args!(
        "error hard fault at pc=0x{:08x}\n",
        frame.pc()
    ));
    debug::exit(EXIT_FAILURE);
    loop {
        cortex_m::asm::bkpt();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    out(format_args!("error panic: {info}\n"));
    debug::exit(EXIT_FAILURE);
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Library log output is encoded (so it costs what it costs on the board) and discarded.
#[defmt::global_logger]
struct Discard;

// SAFETY: the logger keeps no state, so acquire/release need no critical section.
unsafe impl defmt::Logger for Discard {
    fn acquire() {}
    unsafe fn flush() {}
    unsafe fn release() {}
    unsafe fn write(_bytes: &[u8]) {}
}
