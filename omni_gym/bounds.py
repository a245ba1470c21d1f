"""Bounds of the physical inputs read from files and the command line, in one place.

The validators (:mod:`omni_gym.physics.model`, :mod:`omni_gym.io`, :mod:`omni_gym.discrepancy.data.dataset`,
:mod:`omni_gym.discrepancy.synthetic.synth`, :mod:`omni_gym.cli`) check values against these tables, and
``docs/bounds.md`` shows the same tables (rendered by :func:`markdown_table`; a test compares them),
so the documented bounds and the checked bounds cannot drift apart.

Each bound is wide enough for any real wheeled robot of this kind and narrow enough that the
physics stays finite and a run finishes in minutes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Upper bound on lift_rate and recover_rate [1/s]: a mean dwell of 1 ms, two default 0.5 ms substeps.
# The world samples the contact mask once per substep, so faster switching is not resolved by the
# physics (several switches fall inside one substep and only the last counts); it would only add work
# (advance draws every switch) and has no physical meaning for a wheel leaving the floor. The same
# bound for the environments, model files and contact processes (omni_gym.envs.config,
# omni_gym.physics.liftoff); it lives here so the physics imports the utilities, never the reverse.
RATE_MAX = 1e3


@dataclass(frozen=True)
class Bound:
    """Closed interval [lo, hi] (open at lo if ``lo_open``) of one input, with its unit and reason.

    ``name`` is how the user writes the input (JSON key, CSV column, command-line option or
    environment keyword); ``reason`` is the table's last column (the environment keywords' reasons are
    declared with them, :class:`omni_gym.envs.config.EnvConfig`); ``integer`` requires a whole number;
    ``or_zero`` also allows exactly 0 below ``lo``. The one bound class of the package: model, file
    and command-line bounds here, the environment keywords (:data:`omni_gym.envs.config.BOUNDS`) and
    the train/evaluate options (:mod:`agents.options`).
    """

    name: str
    lo: float
    hi: float
    unit: str
    reason: str = ""
    lo_open: bool = False
    integer: bool = False
    or_zero: bool = False

    def interval(self) -> str:
        """The interval as text, e.g. ``[0.001, 10000]``, ``(0, 1]`` or ``0, or [1e-6, 1000]``."""
        return f"0, or {self._range()}" if self.or_zero else self._range()

    def _range(self) -> str:
        left = "(" if self.lo_open else "["
        return f"{left}{_fmt(self.lo, self.integer)}, {_fmt(self.hi, self.integer)}]"

    def contains(self, value: float) -> bool:
        """True if ``value`` is a finite number inside the interval (and whole if ``integer``)."""
        try:
            if not math.isfinite(value):
                return False
        except OverflowError:  # an integer beyond any float (a 400-digit value)
            return False
        if self.integer and value != math.floor(value):
            return False
        if self.or_zero and value == 0:
            return True
        above = value > self.lo if self.lo_open else value >= self.lo
        return above and value <= self.hi

    def within(self) -> str:
        """``in [lo, hi] unit`` (no unit if it has none), the end of :meth:`describe`."""
        unit = f" {self.unit}" if self.unit else ""
        return f"in {self._range()}{unit}"

    def describe(self) -> str:
        """``must be [0 or] a number (an integer) in [lo, hi] unit`` for error messages."""
        kind = "an integer" if self.integer else "a number"
        zero = "0 or " if self.or_zero else ""
        return f"must be {zero}{kind} {self.within()}"

    def check(self, value: float, name: str | None = None) -> float:
        """``value`` if inside the bound; else ValueError ``NAME must be … in [lo, hi] unit, got V``."""
        if not self.contains(value):
            got = repr(value)
            got = got if len(got) <= 60 else got[:57] + "..."  # a message quotes a short excerpt
            raise ValueError(f"{name or self.name} {self.describe()}, got {got}")
        return value


def _fmt(x: float, integer: bool = False) -> str:
    """Compact number: whole numbers below 1e5 (and every integer bound) in full, others as 1e-5, 1e8."""
    if (integer or abs(x) < 1e5) and x == int(x):
        return str(int(x))
    mantissa, _, exponent = f"{x:g}".partition("e")
    return f"{mantissa}e{int(exponent)}" if exponent else mantissa


# Reasons shared by several rows (also by the effect parameters, omni_gym.physics.effects).
MU_REASON = ("real wheel-floor pairs stay below about 2 (`grip` uses 2 for no slip); up to 10 the implicit "
       "step stays stable (stiffness N·μ·(2/π)·k/m ≤ 6·10⁴ /s; above μ ≈ 5 use dt ≤ 0.25 ms, docs/model.md)")
_LENGTH = ("a robot larger than 20 m across is not a wheeled base of this kind; also keeps every lever "
           "arm far inside float range")
RATE_REASON = ("as the environments' `lift_rate`: any tiny rate is safe (a switch beyond the run is never "
         "scheduled, docs/model.md); above 1000 /s a wheel switches within two 0.5 ms substeps, faster than "
         "the contact model resolves")

# --- Model JSON (`--model FILE.json`, `dataset.json`, `gym.make(..., model=...)`) -------------------
# The effect parameters' rows (`effects.EFFECT.KEY`) live with their effects (omni_gym.physics.effects);
# omni_gym.physics.model.MODEL_BOUNDS is this table followed by them, as docs/bounds.md shows it.

# Largest roller angle |γ| [rad] of a wheel (0: omni wheel, π/4: mecanum wheel). A wheel transmits
# drive only through the share cos γ of its rim speed (no-slip wheel speed ∝ 1/cos γ, infinite at
# 90°, where the wheel no longer drives at all); beyond 60° (cos γ < 1/2) no wheel is built, and the
# wheel matrix and the force law's wheel coupling grow steeply.
# π/3 rounded up at the fourth decimal: the bound as docs/bounds.md prints it (1.0472) is accepted.
ROLLER_ANGLE_MAX = 1.0472
ROLLER_ANGLE_REASON = ("0 is an omni wheel (rollers in the wheel plane), ±π/4 (±0.785) a mecanum wheel; beyond ±60° "
                       "(cos γ < 1/2) no wheel is built and the no-slip wheel speed, ∝ 1/cos γ, grows without bound "
                       "towards 90°, where the wheel no longer drives")

WHEELS = "wheels (count)"  # the one wheel-count bound: model files, regularN presets, the environments
MODEL: dict[str, Bound] = {b.name: b for b in (
    Bound("mass", 1e-3, 1e4, "kg", "a 1 g micro-robot to a 10 t industrial omnidirectional platform; "
          "outside, the number is a unit error"),
    Bound("inertia", 1e-7, 1e5, "kg·m²", "m·R² from a 1 g robot 1 cm across to a 10 t one 3 m across"),
    Bound("gravity", 0.1, 100.0, "m/s²", "every surface a wheeled robot has driven on (Moon 1.62, Earth "
          "9.81) and centrifuge tests; must be > 0 for the wheel loads"),
    Bound("wheel_radius", 1e-3, 2.0, "m", "the smallest (1 mm) to the largest (2 m) wheels made"),
    Bound(WHEELS, 3, 16, "", "a planar omnidirectional base needs 3 wheels; more than 16 is not a wheel "
          "layout of this kind (also `regularN` and the environments); checked before anything is built",
          integer=True),
    Bound("wheels[i].position", -10.0, 10.0, "m", "each coordinate; " + _LENGTH),
    Bound("wheels[i].drive (length)", 1e-6, 1e6, "", "a direction only (normalised on input); lengths "
          "outside lose precision when normalised or are typos"),
    Bound("wheels[i].roller_angle", -ROLLER_ANGLE_MAX, ROLLER_ANGLE_MAX, "rad", ROLLER_ANGLE_REASON),
    Bound("com", -10.0, 10.0, "m", "each coordinate, as wheel positions"),
    Bound("rollers", 1, 100, "", "rollers per wheel: commercial omni wheels have 2 to about 30; the "
          "roller pitch 2π/rollers stays far above the wheel's turn in one substep", integer=True),
    Bound("roller_fraction", 0.0, 1.0, "", "share of each roller pitch covered by roller", lo_open=True),
    Bound("body_radius", 1e-3, 20.0, "m", "collision disc; " + _LENGTH),
    Bound("surface.mu_drive", 0.0, 10.0, "", MU_REASON),
    Bound("surface.mu_transverse", 0.0, 10.0, "", MU_REASON),
    Bound("surface.mu_gap", 0.0, 10.0, "", MU_REASON),
    Bound("surface.k", 1.0, 1e4, "s/m", "below 1 s/m the law gives half its limit at 1 m/s slip, no longer "
          "Coulomb friction; above 10⁴ (10x the paper's 1000) the 0.5 ms step does not resolve it"),
)}

# --- Command and dataset files -------------------------------------------------------------------

RUN_SECONDS = 3600.0
FILES: dict[str, Bound] = {b.name: b for b in (
    Bound("t", 0.0, RUN_SECONDS, "s", "one hour: far longer than any tracked run, and replayed in about a "
          "minute at the default 0.5 ms step (7.2·10⁶ substeps)"),
    Bound("w1 … wn", -1e4, 1e4, "rad/s", "commanded wheel speed: about 95,000 rpm, the top speed of the "
          "fastest small motors unloaded; a wheel turns no faster than its motor"),
    Bound("x, y", -1e4, 1e4, "m", "tracked position: 10 km, beyond any tracked area"),
    Bound("theta", -1e4, 1e4, "rad", "tracked heading, wrapped or not: 1600 turns. Trackers wrap it at ±π or "
          "unwrap it from the start of a run; 10⁴ rad takes a robot turning one way at 2.8 rad/s for the longest run "
          "(one hour), so a larger value (99999 rad) is a corrupt cell or another unit"),
    Bound("enc1 … encn", -1e8, 1e8, "rad", "wheel angle: the largest wheel speed for one hour "
          "(3.6·10⁷ rad) with margin"),
    Bound("gyro", -1e3, 1e3, "rad/s", "yaw rate: 30x the range of common MEMS gyros (±2000 °/s = 35 rad/s)"),
)}

# Rates no wheeled robot of this kind reaches, read from a dataset run as a whole (not per cell): a run
# beyond them is in other units (omni_gym.discrepancy.data.units). 20 m/s (72 km/h) is beyond the fastest
# omnidirectional bases (RoboCup small-size robots reach about 5 m/s); 30 rad/s is near the range of
# common MEMS gyros (35 rad/s) and 5 turns a second. A pose in millimetres of a robot moving at
# 2 cm/s, or a heading in degrees of a robot turning at 0.6 rad/s, already exceeds them.
PLAUSIBLE_SPEED = 20.0  # m/s: tracked speed of the geometric centre, and a wheel's commanded rim speed r·|w|
PLAUSIBLE_YAW_RATE = 30.0  # rad/s: tracked heading rate

# --- Logged robot metadata (omni-gym import optiodom) -------------------------------------------
# Wheel sizes and positions are the model's (MODEL above); these are the encoder chain's. A value outside
# turns every wheel reading into 0 or into noise (ngear 1e308 used to import a robot whose wheels never
# turn), so it is refused with the range expected.
LOGS: dict[str, Bound] = {b.name: b for b in (
    Bound("Li", 0.01, 10.0, "m", "the wheel-centre distance (omni3 L; omni4 l1, l2, the wheel spacing): a "
          "centre-to-wheel distance under 1 cm is smaller than any wheel, beyond 10 m outside the model's wheel "
          "positions"),
    Bound("ngear", 0.1, 1000.0, "", "gear ratio n:1 between motor and wheel: 1 is direct drive, planetary "
          "gearheads stop near 1:1000 (a 5 cm wheel then moves at about 3 cm/s at 10,000 motor rpm); below 1:10 the "
          "wheel would turn ten times faster than its motor"),
    Bound("encRes", 1.0, 1e7, "units per motor turn", "1: the log counts revolutions (omni4); "
          "incremental encoders give 12 to about 10⁵ counts per turn, the finest absolute encoders 2²³ (8.4·10⁶)"),
    Bound("travel ratio (tracked / wheels)", 0.02, 3.0, "", "a session's tracked translation (and rotation) "
          "over 1 s baselines against what its wheels' turns give through the nominal wheel matrix: without slip "
          "the two agree (0.95 to 1.13 on the shipped sessions) and slip only shortens the tracked motion, so "
          "three times further is no robot (poses in millimetres give about 1000, a heading in degrees 57, a gear "
          "ratio four times too large 4); 50 times less is no floor (poses in kilometres, encoder units too fine)"),
)}

# --- Command-line options (simulate, synth, gap) --------------------------------------------------

MAX_SUBSTEPS = 2e7
CLI: dict[str, Bound] = {b.name: b for b in (
    Bound("--dt", 1e-5, 2e-3, "s", "simulate's physics substep: above 2 ms the accuracy goal (1 mm, "
          "2 mrad) fails, as the environments refuse; below 10 µs the error (first order, 0.15 mm at "
          "0.5 ms) is already under 3 µm and only the run time grows"),
    Bound("run duration / --dt", 0, MAX_SUBSTEPS, "substeps", "simulate's substeps for the whole commands "
          "file: about two minutes at the measured 2·10⁵ substeps/s; checked before the run starts"),
    Bound("--seed", 0, 2**53, "", "simulate, synth, gap: seeds are written to JSON, whose readers keep "
          "integers exact up to 2^53", integer=True),
    Bound("--jobs", 1, 1024, "", "gap: worker processes (with --ray and no address: the local Ray's CPUs); local "
          "processes beyond this machine's cores are cut to the core count, with a warning (the result does not "
          "depend on the count)", integer=True),
    Bound("--max-effects", 1, 100, "", "gap: effects named one after another; the search also ends when the "
          "candidates (7 today) run out", integer=True),
    Bound("--runs", 1, 1000, "", "synth: runs per dataset; gap's time grows with the runs (10 runs: "
          "about a minute)", integer=True),
    Bound("--duration", 0.2, RUN_SECONDS, "s", "synth: seconds per run; at least one 0.2 s maneuver "
          "step, at most the run length a dataset may have (t above)"),
    Bound("--runs × --duration", 0.0, 2 * RUN_SECONDS, "s", "synth: total simulated time; two hours take "
          "under a minute and about 0.4 GB (measured: 10 × 360 s in 25 s, 0.2 GB, on the shared 2-core "
          "machine), while gap already needs 1–2 min per 50 s of runs"),
    Bound("--noise", 0.0, 1.0, "m", "synth: tracker noise σ. Trackers of wheeled robots: motion capture 0.1-1 mm, "
          "UWB about 0.1 m; above 1 m the noise exceeds the robots' size and a run's travel (a 10 s run at 0.3 m/s "
          "covers 3 m), so the mm-to-cm effects gap looks for cannot show (5 m is consumer-GPS noise, no tracker for "
          "this)"),
    Bound("--hidden viscous_drag c / mass", 0.0, 1e3, "1/s", "synth: the drag force −c·v is applied "
          "explicitly at the 0.5 ms step, stable while c·dt/m < 2; 1000 /s keeps c·dt/m ≤ 0.5"),
)}

# The model table of docs/bounds.md is omni_gym.physics.model.MODEL_BOUNDS (this MODEL and the effects' rows).
SECTIONS: dict[str, dict[str, Bound]] = {"files": FILES, "logs": LOGS, "cli": CLI}


def markdown_table(table: dict[str, Bound]) -> str:
    """The bounds of one table as the markdown table in ``docs/bounds.md``."""
    lines = ["| input | unit | bounds | reason |", "|---|---|---|---|"]
    for b in table.values():
        allowed = ("integer " if b.integer else "") + b.interval()
        lines.append(f"| `{b.name}` | {b.unit or '—'} | {allowed} | {b.reason} |")
    return "\n".join(lines)


def wheel_count() -> tuple[int, int]:
    """(fewest, most) wheels of any robot the package builds: ``MODEL["wheels (count)"]``."""
    b = MODEL[WHEELS]
    return int(b.lo), int(b.hi)
