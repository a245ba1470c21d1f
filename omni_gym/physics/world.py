"""The pymunk world: B robots in one space, wheel forces recomputed at every physics substep.

Each robot is a pymunk dynamic body whose origin is the robot's geometric centre and whose centre of
gravity is the model's centre of mass; a disc shape of ``body_radius`` collides with optional walls
and obstacles. Robot *j* lives in its own arena, offset along x, so robots never touch each other or another
robot's obstacles while sharing one space (and one pymunk step).

One :meth:`World.step` of duration T runs T/dt substeps. A substep reads every body's state through
pymunk's batch API (:mod:`omni_gym.physics.pymunk_batch`), calls the compiled force kernel
(:mod:`omni_gym.physics.kernel`) for all robots at once, writes the effective forces back, and steps
the space. Poses, velocities and wheel states are
returned in each robot's own arena frame (origin at its arena centre).

Default substep dt = 0.5 ms (20 per 10 ms control step): the convergence study
(``benchmarks/convergence.py``) shows it meets 1 mm / 2 mrad against a tight reference over 2 s
with margin, and the linearly-implicit friction step keeps it stable at any friction level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np
import pymunk

from omni_gym.physics.kernel import (
    PARALLEL_MIN_ROBOTS,
    run_substeps,
    run_substeps_parallel,
    run_substeps_spaces,
    substep,
    substep_parallel,
    warm_up,
)
from omni_gym.physics.layout import (
    N_SP,
    N_WH,
    N_WP,
    SP_CX,
    SP_CY,
    SP_INERTIA,
    SP_MASS,
    WH_ANGLE,
    WH_CMD,
    WH_GAP_AT,
    WH_INT,
    WH_LOAD,
    WH_SPEED,
    WP_PX,
    WP_PY,
)
from omni_gym.physics.liftoff import ContactProcess
from omni_gym.physics.loads import wheel_loads
from omni_gym.physics.model import Actuation, SimModel
from omni_gym.physics.pymunk_batch import BodyBatch

DEFAULT_DT = 0.0005  # s, physics substep
# Arena j's origin is at x = ARENA_BASE + j·spacing, with spacing a power of two. All arenas then lie
# inside one binade [2^20, 2^21) (the first one away from its edge), so pymunk's world-coordinate
# arithmetic rounds identically in every arena and robot j of a batch reproduces a lone robot bit for
# bit; the local pose x_world − origin is exact (Sterbenz). Position resolution is
# ulp(2^20) = 2.3e-10 m, far below any physical tolerance.
ARENA_BASE = 1.5 * 2.0**20
ARENA_ROOM = 2.0**19  # m of x along which arenas may be laid out
_NEVER = np.iinfo(np.int64).max  # the switch tick of a robot with no switch scheduled
# A contact switch more than this many substeps after a robot's reset is never reached (at the
# default 0.5 ms it is 71,000 years away) and is not scheduled. Below it, tick counts are exact
# floats, so switch_tick finds the switch substep among five candidates.
SWITCH_HORIZON_TICKS = 2**52
# Fewest robots per pymunk space when a threaded world splits its robots among spaces.
MIN_ROBOTS_PER_SPACE = 32
ROBOT_COLLISION = 1
OBSTACLE_COLLISION = 2


def switch_tick(s: float, dt: float) -> int | None:
    """Smallest k >= 0 with k·dt >= s (the float product the world hands to ``advance``), or None.

    s [s] is a switch time on a robot's local clock, dt [s] the substep. None (no switch) if s is NaN,
    +inf or later than SWITCH_HORIZON_TICKS substeps: the comparison is made in float seconds before
    any integer is formed, so no rate, however small, can overflow or make this loop. Below the
    horizon, ceil(s/dt) is within 2 of the answer (both s/dt and k·dt are correctly rounded and
    k·dt is monotonic in k), so a window of five candidates always holds it.
    """
    if not s <= SWITCH_HORIZON_TICKS * dt:
        return None
    k0 = max(0, math.ceil(s / dt))
    for k in range(max(0, k0 - 2), k0 + 3):
        if k * dt >= s:
            return k
    raise RuntimeError(f"no switch tick near {k0} for s={s!r}, dt={dt!r}")  # unreachable, see above


@dataclass(frozen=True)
class Arena:
    """A rectangular arena ``[-half_size, half_size]²`` [m] with optional walls and disc obstacles.

    obstacles: (x, y, radius) [m] in the arena frame.
    """

    half_size: float = 5.0
    walls: bool = False
    obstacles: tuple[tuple[float, float, float], ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.half_size) and self.half_size > 0):
            raise ValueError(f"arena half_size must be a positive number [m], got {self.half_size}")
        for o in self.obstacles:
            if len(o) != 3 or not all(math.isfinite(v) for v in o) or o[2] <= 0:
                raise ValueError(f"obstacle must be (x, y, radius>0) finite numbers [m], got {o}")


class World:
    """B robots of one wheel count, simulated together in one pymunk space.

    Args:
        models: one :class:`SimModel` for all robots, or a list with one per robot (parameters
            may differ, e.g. for domain randomisation; the wheel count must be the same).
        n_robots: number of robots B (ignored when ``models`` is a list).
        dt: physics substep [s].
        actuation: wheel actuation shared by all robots.
        arena: walls and obstacles, replicated in each robot's arena.
        parallel: share the force kernel among threads (default: from 256 robots on).
    """

    def __init__(self, models: SimModel | list[SimModel], n_robots: int = 1, dt: float = DEFAULT_DT,
                 actuation: Actuation | None = None, arena: Arena | None = None,
                 parallel: bool | None = None) -> None:
        model_list = list(models) if isinstance(models, (list, tuple)) else [models] * int(n_robots)
        if not model_list:
            raise ValueError("World needs at least one robot")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt}")
        n = model_list[0].n_wheels
        if any(m.n_wheels != n for m in model_list):
            raise ValueError("all robots of a World must have the same number of wheels")
        self.dt = float(dt)
        self.actuation = actuation or Actuation()
        self.arena = arena or Arena()
        self.n_robots = B = len(model_list)
        self.n_wheels = n
        self.spacing = 2.0 ** math.ceil(math.log2(2.0 * self.arena.half_size + 4.0))
        if (B + 1) * self.spacing > ARENA_ROOM:
            raise ValueError(f"too many robots ({B}) for arenas of {self.spacing:g} m in one space")
        self.origins = np.zeros((B, 2))
        self.origins[:, 0] = ARENA_BASE + np.arange(B) * self.spacing
        self.tick = 0  # substeps run since construction (global clock of the space)
        self.start_tick = np.zeros(B, dtype=np.int64)  # tick of each robot's last reset: its local t = 0
        # State and parameter arrays (robot-major, contiguous: the kernel reads them directly).
        self.sp = np.zeros((B, N_SP))
        self.wp = np.zeros((B, n, N_WP))
        # Wheel state packed in one array the kernel reads; the named attributes are views of it.
        self.wheels = np.zeros((B, n, N_WH))
        self.wheel_angle = self.wheels[:, :, WH_ANGLE]  # rad
        self.wheel_speed = self.wheels[:, :, WH_SPEED]  # rad/s
        self.wheel_cmd = self.wheels[:, :, WH_CMD]  # rad/s
        self.servo_int = self.wheels[:, :, WH_INT]  # rad
        self.loads = self.wheels[:, :, WH_LOAD]  # N
        self.wheels[:, :, WH_GAP_AT] = math.nan  # the kernel's rigid-material memo starts empty
        self.contact = np.ones((B, n), dtype=bool)
        self.ext_force = np.zeros((B, 3))
        self.force = np.zeros((B, 3))
        self.slip = np.zeros((B, n, 2))
        self.collided = np.zeros(B, dtype=bool)
        self.contact_processes: list[ContactProcess | None] = [None] * B
        self._switch_tick = np.full(B, _NEVER, dtype=np.int64)  # global tick of each robot's next contact switch
        self._next_switch_tick = _NEVER
        self.models: list[SimModel] = list(model_list)
        # Wheel loads [N] of robot j per contact mask (mask bytes → loads), cleared by set_model: a lift-off
        # process switches among a few masks, and recomputing the static balance at every switch and reset
        # cost more than the switch itself.
        self._load_cache: list[dict[bytes, np.ndarray]] = [{} for _ in range(B)]
        # Threaded force kernel for large batches (bit-identical results); None chooses by size.
        self.parallel = B >= PARALLEL_MIN_ROBOTS if parallel is None else bool(parallel)
        self._build_space(model_list)
        for j, m in enumerate(model_list):
            self.set_model(j, m)
        self._kernel = substep_parallel if self.parallel else substep
        self._loop = run_substeps_parallel if self.parallel else run_substeps
        warm_up(self._kernel)

    # --- pickling: rebuild the space, then restore every state variable exactly ------------------

    _STATE_ARRAYS = ("wheels", "contact", "ext_force",
                     "force", "slip", "collided", "start_tick", "_switch_tick", "sp", "wp")

    def __getstate__(self) -> dict:
        self._read_state()
        return {
            "init": (list(self.models), self.dt, self.actuation, self.arena, self.parallel),
            "arrays": {k: getattr(self, k).copy() for k in self._STATE_ARRAYS},
            "bodies": self._state_view.copy(),
            "tick": self.tick,
            "contact_processes": list(self.contact_processes),
            "next_switch_tick": self._next_switch_tick,
        }

    def __setstate__(self, state: dict) -> None:
        models, dt, actuation, arena, parallel = state["init"]
        self.__init__(models, dt=dt, actuation=actuation, arena=arena, parallel=parallel)
        for key, value in state["arrays"].items():
            getattr(self, key)[...] = value
        for body, row in zip(self.bodies, state["bodies"], strict=True):
            body.angle = row[2]
            body.position = (row[0], row[1])
            body.velocity = (row[3], row[4])
            body.angular_velocity = row[5]
            body.space.reindex_shapes_for_body(body)
        self.tick = state["tick"]
        self.contact_processes = state["contact_processes"]
        self._next_switch_tick = state["next_switch_tick"]

    # --- copying one robot's state into others (planners: rollouts from the true state) ------------

    # Every per-robot state array but the clocks, which copy_robot moves onto this world's tick.
    _ROBOT_ROWS = tuple(k for k in _STATE_ARRAYS if k not in ("start_tick", "_switch_tick"))

    def copy_robot(self, source: World, j: int, robots: np.ndarray | list[int] | None = None,
                   contacts: str = "hold") -> None:
        """Make each robot of ``robots`` (default all) an exact copy of robot ``j`` of ``source``.

        Copied: the parameters (the kernel's rows and the body's mass, moment and centre of gravity), the
        body's pose in its arena frame and its velocity, every wheel state (angle, speed, command, PI
        integral, load, the rigid-material memo), the contact mask, the external force, the collision flag
        and the robot's local clock. ``source`` may be this world. Stepped with the same commands, a copy
        reproduces the source robot bit for bit: arenas share one binade (:data:`ARENA_BASE`), so the local
        pose moves between them exactly, and the body's internal centre of gravity is set directly, not
        through pymunk's position setter (which adds the rotated offset, one rounding away).

        ``contacts``: ``"hold"`` keeps the copied mask for as long as the copy runs (no contact process:
        a planner that knows which wheels are up now, not when they will lift); ``"copy"`` gives each copy
        an independent deep copy of the source's contact process, generator included (the source's future
        lift-off schedule: the copy and the source switch on the same substeps).
        """
        import copy

        if contacts not in ("hold", "copy"):
            raise ValueError(f"contacts must be 'hold' or 'copy', got {contacts!r}")
        if source.n_wheels != self.n_wheels or source.dt != self.dt or source.actuation != self.actuation:
            raise ValueError("copy_robot: the worlds differ in wheel count, substep or actuation")
        if not 0 <= j < source.n_robots:
            raise IndexError(f"copy_robot: robot {j} out of range for a world of {source.n_robots}")
        idx = np.arange(self.n_robots) if robots is None else np.asarray(robots, dtype=int).reshape(-1)
        src = source.bodies[j]
        cog = src.center_of_gravity
        angle, vel, omega = src.angle, src.velocity, src.angular_velocity
        # pymunk's position is the body origin, p − R(θ)·cog, one rounding from the internal centre of
        # gravity p that it integrates. With cog set to 0 and the angle set again (which rebuilds the
        # transform from p), the position reads p exactly; the same two steps put it back.
        src.center_of_gravity = (0.0, 0.0)
        src.angle = angle
        p = src.position
        src.center_of_gravity = cog
        src.angle = angle
        local = (p[0] - source.origins[j, 0], p[1] - source.origins[j, 1])  # exact: one binade
        age = source.tick - int(source.start_tick[j])
        proc = source.contact_processes[j]
        for k in idx:
            k = int(k)
            if source is self and k == j:
                continue
            for name in self._ROBOT_ROWS:
                getattr(self, name)[k] = getattr(source, name)[j]
            body = self.bodies[k]
            if body.mass != src.mass or body.moment != src.moment:  # a change makes pymunk re-check the body
                body.mass = src.mass
                body.moment = src.moment
            body.center_of_gravity = (0.0, 0.0)
            body.angle = angle
            body.position = (self.origins[k, 0] + local[0], self.origins[k, 1] + local[1])
            body.center_of_gravity = cog
            body.angle = angle
            body.velocity = vel
            body.angular_velocity = omega
            body.space.reindex_shapes_for_body(body)
            self.models[k] = source.models[j]
            self._load_cache[k] = dict(source._load_cache[j])
            self.start_tick[k] = self.tick - age
            self.contact_processes[k] = copy.deepcopy(proc) if contacts == "copy" and proc is not None else None
            if self.contact_processes[k] is None:
                self._switch_tick[k] = _NEVER
            else:  # the source's pending switch, on this world's clock
                pending = int(source._switch_tick[j])
                self._switch_tick[k] = _NEVER if pending == _NEVER else pending - source.tick + self.tick
        self._next_switch_tick = int(self._switch_tick.min())

    def place(self, robots: np.ndarray | list[int], poses: np.ndarray, velocities: np.ndarray) -> None:
        """Put robots at ``poses`` (k, 3) [m, m, rad] (geometric centre, arena frame) moving at ``velocities``
        (k, 3): ẋ, ẏ [m/s] of the geometric centre (world frame) and ω [rad/s], as :attr:`pose` and
        :attr:`velocity` read them. Wheel states, contacts and clocks are left as they are (a planner that
        replaces a copied robot's pose by an estimate)."""
        idx = np.asarray(robots, dtype=int).reshape(-1)
        poses = np.asarray(poses, dtype=float).reshape(len(idx), 3)
        velocities = np.asarray(velocities, dtype=float).reshape(len(idx), 3)
        if not (np.all(np.isfinite(poses)) and np.all(np.isfinite(velocities))):
            raise ValueError("place: poses and velocities must be finite")
        for row, j in enumerate(idx):
            body = self.bodies[j]
            theta, om = poses[row, 2], velocities[row, 2]
            cx, cy = self.sp[j, SP_CX], self.sp[j, SP_CY]
            c, s = math.cos(theta), math.sin(theta)
            rx, ry = c * cx - s * cy, s * cx + c * cy  # the centre of gravity's offset, world frame
            body.angle = theta
            body.position = (self.origins[j, 0] + poses[row, 0], self.origins[j, 1] + poses[row, 1])
            body.velocity = (velocities[row, 0] - om * ry, velocities[row, 1] + om * rx)  # v_com = v + ω × ρ
            body.angular_velocity = om
            body.space.reindex_shapes_for_body(body)

    # --- construction ---------------------------------------------------------------------------

    def _build_space(self, models: list[SimModel]) -> None:
        # Robots only get collision shapes when there is something to hit: each robot is alone in its
        # arena, and shapes without partners would only cost broad-phase time (2.5x the step at B = 1024).
        self._has_obstacles = self.arena.walls or bool(self.arena.obstacles)
        # A threaded world without obstacles splits its robots among several spaces, one per thread,
        # each stepped by its thread (pymunk's step is then parallel too). Robots never interact and
        # pymunk integrates each body on its own, so the split changes no bit (tests/test_world.py).
        # With obstacles, collision callbacks run Python, which needs the one thread holding the GIL.
        n_spaces = 1
        if self.parallel and not self._has_obstacles:
            n_spaces = max(1, min(numba.get_num_threads(), self.n_robots // MIN_ROBOTS_PER_SPACE))
        self._bounds = np.linspace(0, self.n_robots, n_spaces + 1).round().astype(np.int64)
        self.spaces = [pymunk.Space() for _ in range(n_spaces)]
        self.space = space = self.spaces[0]
        self.bodies: list[pymunk.Body] = []
        for k, sp in enumerate(self.spaces):
            sp.iterations = 10
            for j in range(int(self._bounds[k]), int(self._bounds[k + 1])):
                m = models[j]
                body = pymunk.Body(m.robot.mass, m.robot.inertia)
                body.position = tuple(self.origins[j])
                sp.add(body)
                if self._has_obstacles:
                    shape = pymunk.Circle(body, m.robot.body_radius)
                    shape.collision_type = ROBOT_COLLISION
                    shape.friction = 0.3
                    shape.elasticity = 0.0
                    sp.add(shape)
                self.bodies.append(body)
                self._add_arena(j)
        if self._has_obstacles:
            index = {b: j for j, b in enumerate(self.bodies)}

            def begin(arbiter: pymunk.Arbiter, _space: pymunk.Space, _data) -> None:
                for s in arbiter.shapes:
                    if s.body in index:
                        self.collided[index[s.body]] = True

            space.on_collision(ROBOT_COLLISION, OBSTACLE_COLLISION, begin=begin)
        # One batched read of (position, angle, velocity, angular velocity) per body and one batched
        # write of (force, torque) per space, through the module that owns pymunk's internals.
        self._batches = [BodyBatch(sp, int(self._bounds[k + 1] - self._bounds[k])) for k, sp in enumerate(self.spaces)]
        self._batch = self._batches[0]
        self._c_tables = np.stack([b.c_table for b in self._batches])
        if n_spaces == 1:
            self._state_view = self._batch.states
            self._force_view = self._batch.forces
        else:  # the spaces' states gathered after each run (World.pose, the environments read this)
            self._state_view = np.zeros((self.n_robots, 6))
            self._force_view = None

    def _add_arena(self, j: int) -> None:
        ox, oy = self.origins[j]
        h = self.arena.half_size
        static = self.space.static_body  # one space whenever there are walls or obstacles
        shapes = []
        if self.arena.walls:
            corners = [(-h, -h), (h, -h), (h, h), (-h, h)]
            for k in range(4):
                a = corners[k]
                b = corners[(k + 1) % 4]
                shapes.append(pymunk.Segment(static, (ox + a[0], oy + a[1]), (ox + b[0], oy + b[1]), 0.01))
        for x, y, rad in self.arena.obstacles:
            shapes.append(pymunk.Circle(static, rad, offset=(ox + x, oy + y)))
        for s in shapes:
            s.collision_type = OBSTACLE_COLLISION
            s.friction = 0.3
        if shapes:
            self.space.add(*shapes)

    def set_model(self, j: int, model: SimModel) -> None:
        """Give robot j new parameters (mass, friction, effects...), keeping its state."""
        if model.n_wheels != self.n_wheels:
            raise ValueError(f"robot {j}: model has {model.n_wheels} wheels, world has {self.n_wheels}")
        sp, wp = model.kernel_params(self.actuation)
        self.sp[j] = sp
        self.wp[j] = wp
        self.wheels[j, :, WH_GAP_AT] = math.nan  # a new pitch, gap or phase: forget the kernel's memo
        body = self.bodies[j]
        body.mass = sp[SP_MASS]
        body.moment = sp[SP_INERTIA]
        body.center_of_gravity = tuple(sp[[SP_CX, SP_CY]])  # after the effects (com_offset)
        self.models[j] = model
        self._load_cache[j] = {}
        self._update_loads(j)

    # --- state access --------------------------------------------------------------------------

    def reset(self, poses: np.ndarray | None = None, robots: np.ndarray | list[int] | None = None) -> None:
        """Put robots at rest at ``poses`` (k, 3) [m, m, rad] in their arena frames (default origin).

        Wheel angles, speeds, commands, PI states and collision flags of those robots are zeroed.
        """
        idx = np.arange(self.n_robots) if robots is None else np.asarray(robots, dtype=int)
        if poses is None:
            poses = np.zeros((len(idx), 3))
        poses = np.asarray(poses, dtype=float).reshape(len(idx), 3)
        if not np.all(np.isfinite(poses)):
            raise ValueError("reset: poses must be finite")
        for row, j in enumerate(idx):
            body = self.bodies[j]
            body.angle = poses[row, 2]
            body.position = (self.origins[j, 0] + poses[row, 0], self.origins[j, 1] + poses[row, 1])
            body.velocity = (0.0, 0.0)
            body.angular_velocity = 0.0
            body.space.reindex_shapes_for_body(body)
        for arr in (self.wheel_angle, self.wheel_speed, self.wheel_cmd, self.servo_int, self.slip):
            arr[idx] = 0.0
        self.collided[idx] = False
        self.start_tick[idx] = self.tick
        for j in idx:
            proc = self.contact_processes[j]
            if proc is not None:
                proc.reset(0.0)
                self.contact[j] = proc.mask
                self._update_loads(j)
            self._schedule_switch(j)
        self._next_switch_tick = int(self._switch_tick.min())

    def set_commands(self, wheel_speeds: np.ndarray) -> None:
        """Commanded wheel speeds [rad/s], shape (B, n) (or (n,) for one robot); held until changed."""
        w = np.asarray(wheel_speeds, dtype=float)
        if w.shape != self.wheel_cmd.shape:
            w = w.reshape(self.wheel_cmd.shape) if w.size == self.wheel_cmd.size else w
        if w.shape != self.wheel_cmd.shape:
            raise ValueError(f"commands must have shape {self.wheel_cmd.shape}, got {np.shape(wheel_speeds)}")
        if not np.all(np.isfinite(w)):
            raise ValueError("commands contain NaN or infinity")
        self.wheel_cmd[:] = w

    def set_contact(self, j: int, mask: np.ndarray) -> None:
        """Contact mask of robot j (True = wheel on the floor); loads follow from static balance."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self.n_wheels,):
            raise ValueError(f"contact mask must have {self.n_wheels} entries, got {mask.shape}")
        self.contact[j] = mask
        self._update_loads(j)

    def set_contact_process(self, j: int, process: ContactProcess | None) -> None:
        """Drive robot j's contact mask by a random process (None: all wheels down)."""
        self.contact_processes[j] = process
        if process is None:
            self.set_contact(j, np.ones(self.n_wheels, dtype=bool))
        else:
            process.reset(self.local_time(j))
            self.set_contact(j, process.mask)
        self._schedule_switch(j)
        self._next_switch_tick = int(self._switch_tick.min())

    def _update_loads(self, j: int) -> None:
        key = self.contact[j].tobytes()
        loads = self._load_cache[j].get(key)
        if loads is None:
            # Wheel positions and centre of mass as the kernel sees them (after the model's effects).
            positions = self.wp[j][:, [WP_PX, WP_PY]]
            com = self.sp[j, [SP_CX, SP_CY]]
            loads = wheel_loads(positions, com, self.sp[j, SP_MASS], self.models[j].gravity, self.contact[j])
            self._load_cache[j][key] = loads
        self.loads[j] = loads

    @property
    def time(self) -> float:
        """Seconds simulated since construction."""
        return self.tick * self.dt

    def local_time(self, j: int) -> float:
        """Seconds since robot j's last reset (its contact process and sensors run on this clock)."""
        return (self.tick - int(self.start_tick[j])) * self.dt

    def _schedule_switch(self, j: int) -> None:
        """Global tick of the first substep whose local time k·dt reaches robot j's next switch.

        Integer ticks make a robot's switches fall on the same substeps whatever the other robots
        do and whenever it was reset, so a batch reproduces lone robots exactly. A switch that never
        comes (rate 0: ``next_switch`` = inf) or lies beyond SWITCH_HORIZON_TICKS (a tiny rate) is
        not scheduled (``_NEVER``).
        """
        proc = self.contact_processes[j]
        k = None if proc is None else switch_tick(proc.next_switch, self.dt)
        self._switch_tick[j] = _NEVER if k is None else int(self.start_tick[j]) + k

    def _advance_contacts(self, tick: int) -> None:
        for j in np.flatnonzero(self._switch_tick <= tick):
            proc = self.contact_processes[j]
            if proc.advance((tick - int(self.start_tick[j])) * self.dt):
                self.contact[j] = proc.mask
                self._update_loads(j)
            self._schedule_switch(j)
        self._next_switch_tick = int(self._switch_tick.min())

    def _read_state(self) -> None:
        if len(self._batches) == 1:
            self._batch.read()
            return
        for k, batch in enumerate(self._batches):
            batch.read()
            self._state_view[self._bounds[k]:self._bounds[k + 1]] = batch.states

    def body_states(self) -> np.ndarray:
        """(B, 6): each robot's centre of mass x, y [m] in the space's frame (its arena origin included,
        :attr:`origins`), heading θ [rad], world-frame velocity vx, vy [m/s] and yaw rate ω [rad/s], read now.

        The array is the world's own buffer, not a copy: it is refreshed by the next call and must not be
        written. The environments' compiled observation reads it once per control period; :attr:`pose` and
        :attr:`velocity` are the copying, geometric-centre forms.
        """
        self._read_state()
        return self._state_view

    @property
    def pose(self) -> np.ndarray:
        """(B, 3): x, y [m] of each geometric centre in its arena frame, heading θ [rad]."""
        st = self.body_states()
        out = st[:, 0:3].copy()
        out[:, 0:2] -= self.origins
        return out

    @property
    def velocity(self) -> np.ndarray:
        """(B, 3): world-frame velocity ẋ, ẏ [m/s] of each geometric centre and yaw rate [rad/s]."""
        st = self.body_states()
        theta, om = st[:, 2], st[:, 5]
        com = self.sp[:, [SP_CX, SP_CY]]
        c, s = np.cos(theta), np.sin(theta)
        rx = c * com[:, 0] - s * com[:, 1]
        ry = s * com[:, 0] + c * com[:, 1]
        # v_centre = v_com + ω × (centre − com) = v_com − ω × ρ_com
        return np.column_stack([st[:, 3] + om * ry, st[:, 4] - om * rx, om])

    # --- stepping -----------------------------------------------------------------------------

    def step(self, duration: float) -> None:
        """Advance every robot by ``duration`` [s] (rounded to whole substeps, at least one)."""
        steps = max(1, int(round(duration / self.dt)))
        self.substeps(steps)

    def substeps(self, count: int) -> None:
        """Run ``count`` physics substeps of ``dt``.

        The substeps between two contact switches run in one compiled call (``run_substeps*`` in
        :mod:`omni_gym.physics.kernel`): read, kernel, write and pymunk step, each substep the same calls
        as a Python loop would make, so results do not depend on where switches split the run.
        """
        for batch in self._batches:
            batch.check_new_bodies()
        dt = self.dt
        if len(self._batches) == 1:
            loop, table = self._loop, self._batch.c_table
            args = (self._state_view, self.wheels, self.sp, self.wp, self.ext_force, self._force_view, self.slip)
        else:
            loop, table = run_substeps_spaces, self._c_tables
            args = (self._bounds, self._state_view, self.wheels, self.sp, self.wp, self.ext_force, self.slip)
        left = int(count)
        while left > 0:
            if self.tick >= self._next_switch_tick:
                self._advance_contacts(self.tick)
            # Up to the next switch (at least one substep: a switch is handled once per tick).
            chunk = min(left, max(1, self._next_switch_tick - self.tick))
            loop(chunk, table, dt, *args)
            self.tick += chunk
            left -= chunk
