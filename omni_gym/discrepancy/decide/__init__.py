"""Stage 4, decide: which fitted candidate, if any, explains the gap on runs its fit never saw.

* :mod:`.decision`: rank the candidates by held-out score; name the effect, ``none`` or ``unexplained``.
* :mod:`.score`: whole runs replayed open loop by several models (``omni-gym score``; ``gap``'s
  drift-aware held-out check).

Imports the earlier stages only (``tests/test_architecture.py``).
"""
