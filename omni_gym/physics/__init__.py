"""The physics: robot geometry, kinematics, friction, wheel loads, lift-off, the simulation model,
the force kernel, the pymunk world and open-loop replay. The bottom layer of the package: it
imports no environment, discrepancy, agent or command-line code (``tests/test_architecture.py``).

* :mod:`.robot`: wheel layouts and robot presets (body frame, metres).
* :mod:`.kinematics`: the wheel matrix, body twist ↔ wheel speeds.
* :mod:`.friction`: surfaces and the regularised-Coulomb friction law, roller gaps.
* :mod:`.loads`: normal load per wheel from the centre of mass and the contact set.
* :mod:`.liftoff`: random and scheduled wheel contact processes.
* :mod:`.model`: :class:`~.model.SimModel` (robot + surface + effects) and its JSON form.
* :mod:`.effects`: the effect library, one module per model effect, and its registry.
* :mod:`.layout`: every column index of the kernel's arrays.
* :mod:`.kernel`: the numba force kernel of one substep.
* :mod:`.pymunk_batch`: pymunk's batch internals, behind a checked version range.
* :mod:`.world`: :class:`~.world.World`, B robots in one pymunk space.
* :mod:`.replay`: :func:`~.replay.simulate_commands`, open-loop replay of wheel commands.
"""
