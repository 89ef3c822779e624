"""The board's settings: loop rate, motor constants, limits and protections.

Integers in the units their names say (mA, µA, mV, mΩ, ms, counts), because the reference
board's Cortex-M0+ has no floating-point unit and MicroPython allocates every float. A board
reads overrides from ``config.json`` on its file system (docs/legs-build.md); the simulated
board passes them from its command line.
"""


class Config:
    """Defaults for the reference build (docs/legs-build.md); every value may be overridden."""

    board_name = "slopelander-legs-rp2040"
    tick_ms = 4  # the current loop and the leg state machines run at 250 Hz
    status_ms = 100  # STATUS period when HELLO asks for 0
    silence_ms = 10000  # companion silent this long: HOLDING legs switch their motors off
    # motor (10 g 1:298 micro gear motor, DRV8874 driver, 5 V supply)
    v_max_mv = 3000  # drive limit (PWM duty of the supply)
    v_bus_mv = 5000  # motor supply
    r_mohm = 1900  # winding resistance, for the hold voltage's feed-forward
    soft_start_mv = 300  # voltage step per tick when starting (3 V in 40 ms)
    counts_per_mm = 2980  # motor encoder (x1 of 3 cycles/rev) through 1:298 and 0.3 mm/rev
    # the clamp: full speed until the load current reaches the target, brake, hold the current
    accel_ms = 200  # after a start the current is the rotor's, not the load's, for this long
    lead_ua = 1200  # at full speed, brake this far below the target (less in proportion when slower):
    # the rotor runs on into it while it stops, and the hold's noise adds a little
    brake_ms = 120  # brake this long before the hold (six mechanical time constants)
    hold_gain_pct = 10  # hold loop: µV of integral per µA of error per tick (R/20 per tick)
    hold_still_ms = 250  # the hold's integral acts once the encoder has been still this long
    hold_deadband_ua = 1000  # and not for errors smaller than this (the sensor's noise)
    hold_integral_mv = 100  # limit of the hold loop's integral term (the winding's resistance varies ±20 %)
    creep_ms = 1000  # the rotor crept on (2 counts) over a window this long in the hold: short, run on
    max_reruns = 2  # runs on from a hold that crept, at most, per clamp
    filter_shift = 2  # current filter: new = old + (sample - old) >> 2 (about 14 ms)
    band_ua = 2000  # |current - target| counted as on target
    settle_ms = 300  # on target this long: HOLDING
    slow_ma = 30  # a step smaller than this (mA) starts gently: speed in proportion to it
    # protections
    overcurrent_ma = 1800  # above the stall current: a shorted winding or driver
    endstop_ma = 300  # reverse current with the encoder still: the nut is at its back stop
    stall_ms = 100  # driven above stall_mv with no encoder count this long: STUCK
    stall_mv = 1000
    # driven above sense_mv (a stalled motor then draws 30 mA, a turning one its no-load 40 mA)
    # with less current than sense_floor_ua for sense_ms: SENSE (current sense or wiring open)
    sense_mv = 60
    sense_floor_ua = 5000
    sense_ms = 40
    early_mm_pct = 50  # target reached with the nut under this % of the clearance: STUCK
    clearance_mm_x100 = 290  # nut travel before the stack (2.9 mm)
    max_travel_mm_x100 = 620  # clearance + stack to flat + margin: beyond it, TRAVEL
    stop_slack_mm_x100 = 30  # the back stop found this far before where the encoder says: STUCK
    motion_limit_ms = 30000  # a motion longer than this: TIMEOUT
    boot_probe_ms = 60  # at power-up, a gentle reverse pull tells a loose nut from a clamped one
    boot_probe_mv = 1000
    # SET_FRICTION above this is refused (NAK above_limit): the stack goes flat near 180 mA
    max_target_ma = 175
    # sensing on the reference board (legfw.rp2040)
    adc_ref_mv = 3300  # the MCP3204's reference
    sense_mv_per_a = 1100  # IPROPI volts per amp through the carrier's resistor: measure yours
    angle_zero_cdeg = (0, 0, 0, 0)  # each AS5600's reading with its leg folded (0 deg)
    # rest stops (hobby servos; optional, the ANGLE_STOP capability)
    angle_stop = False
    stop_speed_cdeg_s = 1500  # rest-stop speed, 15 deg/s
    angle_band_cdeg = 20  # leg within 0.2 deg of the stop: positioned

    def __init__(self, **overrides) -> None:
        for key in overrides:
            if not hasattr(Config, key) or key.startswith("_"):
                raise ValueError(f"unknown setting {key!r}")
            default = getattr(Config, key)
            value = overrides[key]
            if isinstance(default, tuple) and isinstance(value, list):
                value = tuple(value)  # JSON has lists only
            if type(value) is not type(default):
                raise ValueError(f"setting {key} must be {type(default).__name__}, not {value!r}")
            setattr(self, key, value)

    @classmethod
    def load(cls, path: str, rest_stops: bool):
        """A board's settings at power-up: the defaults, overridden by ``path`` if it exists, and
        refused here if the board cannot carry them out (``rest_stops``: it has the servos):
        refused later, with the watchdog running, they would reboot the board in a loop."""
        try:
            cfg = cls.from_json(path)
        except OSError:  # no config.json: the reference build's defaults
            cfg = cls()
        if cfg.angle_stop and not rest_stops:
            raise ValueError(
                f"{path}: setting angle_stop is true, but this board has no rest-stop servos: "
                'set "angle_stop": false'
            )
        return cfg

    @classmethod
    def from_json(cls, path: str):
        """Defaults overridden by a JSON object in ``path`` (the board's ``config.json``)."""
        import json

        with open(path) as f:
            return cls(**json.load(f))
