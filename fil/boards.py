"""The boards the firmware-in-the-loop stage 1 runs the shipped ELF of (src/board/<folder>/):
what differs between them as QEMU's netduinoplus2 (STM32F405) sees them. The USART2, IWDG,
SYSCFG/EXTI and flash-size addresses are the same on all of them.

Each script takes `--board NAME` (default `f407`).
"""

BOARDS = {
    "f407": dict(
        # The part's flash size (the flash-size word the boot assist answers), and a smaller
        # one the storage map does not fit (degraded boot).
        flash_kib=1024, small_kib=512,
        # The storage regions (the board's flash.rs and memory.x): parameters, runs.
        param_addr=0x08004000, param_len=32 * 1024,
        run_addr=0x080C0000, run_len=256 * 1024,
        # The external clock the boot assist reports (Hz: the board's first documented one,
        # src/board/crystal.rs), and one none of its documented ones is (unknown crystal).
        crystal_hz=8_000_000, unknown_hz=12_000_000,
        # The end of the boot line with the external clock running (the board's CLOCK_TEXTS).
        clock_note="clock: 8 MHz crystal (HSE), 168 MHz",
        # ... and on the internal oscillator.
        internal_note="clock: internal oscillator (HSI 16 MHz), 168 MHz",
        # The fault event without the external clock.
        no_clock_fault=("no crystal: HSE did not start, running on the internal oscillator "
                        "(HSI, 168 MHz through the PLL; timing and baud rate within a few %)"),
        # The motors' port as QEMU's unimplemented-device log names it, its RCC_AHB1RSTR bit,
        # the PWM and enable pins, the enable pin, and the control timer (its name, and QEMU's
        # name for it in that log).
        motor_port="GPIOE", port_reset_bit=4, motor_pins=(9, 11, 13), enable_pin=13,
        # The motor port's pins the boot makes inputs (none: port E has only the motor and
        # direction pins).
        port_inputs=(),
        timer_name="TIM7", control_timer="timer[7]",
    ),
    "nucleo-f446re": dict(
        flash_kib=512, small_kib=256,
        param_addr=0x08004000, param_len=32 * 1024,
        run_addr=0x08040000, run_len=256 * 1024,
        crystal_hz=8_000_000, unknown_hz=12_000_000,
        clock_note="clock: ST-LINK MCO 8 MHz (HSE bypass), 180 MHz",
        internal_note=("clock: internal oscillator (HSI 16 MHz), 180 MHz, no ST-LINK MCO at "
                       "power-up"),
        no_clock_fault=("no external clock: the ST-LINK's 8 MHz MCO (HSE bypass) did not start, "
                        "running on the internal oscillator (HSI, 180 MHz through the PLL; "
                        "timing and baud rate within a few %)"),
        motor_port="GPIOA", port_reset_bit=0, motor_pins=(8, 9, 10), enable_pin=10,
        # PA0/PA1 (encoder) become alternate functions: no port A pin is made an input.
        port_inputs=(),
        timer_name="TIM7", control_timer="timer[7]",
    ),
    "blackpill-f411ce": dict(
        flash_kib=512, small_kib=256,
        param_addr=0x08004000, param_len=32 * 1024,
        run_addr=0x08040000, run_len=256 * 1024,
        crystal_hz=25_000_000, unknown_hz=12_000_000,
        # The board's other documented crystals and the boot line's clock note with each.
        more_crystals=((8_000_000, "clock: 8 MHz crystal (HSE), 100 MHz"),),
        clock_note="clock: 25 MHz crystal (HSE), 100 MHz",
        internal_note="clock: internal oscillator (HSI 16 MHz), 100 MHz",
        no_clock_fault=("no crystal: HSE did not start, running on the internal oscillator "
                        "(HSI, 100 MHz through the PLL; timing and baud rate within a few %)"),
        motor_port="GPIOA", port_reset_bit=0, motor_pins=(8, 9, 1), enable_pin=1,
        # PA15 (right encoder A, a JTAG alternate function out of reset) is made an input
        # before TIM2 takes it; PA0 (KEY) is an input from reset (its mode is not written).
        port_inputs=(15,),
        timer_name="TIM11", control_timer="timer[11]",
    ),
}


def board(name):
    """The profile of board `name` (a key of BOARDS)."""
    if name not in BOARDS:
        raise SystemExit(f"unknown board {name!r}: one of {', '.join(BOARDS)}")
    return dict(BOARDS[name], name=name)


def boot_tail(profile):
    """What the shipped ELF's boot line says after the board's clock in QEMU: that the control
    timer does not count (QEMU models neither TIM7 nor TIM11). Taken from the F407's boot line in
    the golden console transcript (its one statement on this side), with the board's timer."""
    import os
    golden = os.path.join(os.path.dirname(os.path.abspath(__file__)), "golden", "console.txt")
    f407 = BOARDS["f407"]
    for line in open(golden):
        if line.startswith("< event boot: ") and ("; " + f407["clock_note"]) in line:
            tail = line.rstrip("\n").split("; " + f407["clock_note"], 1)[1]
            return tail.replace(f"control timer {f407['timer_name']} ",
                                f"control timer {profile['timer_name']} ")
    raise SystemExit(f"no boot line with `{f407['clock_note']}` in {golden}")
