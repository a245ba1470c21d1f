"""Stage 5, report: what a ``gap`` run writes.

* :mod:`.report`: ``result.json``, ``report.md`` and its plots, written atomically into the report folder.
* :mod:`.finite`: standard JSON only (non-finite numbers become ``null``).

Imports the earlier stages only (``tests/test_architecture.py``).
"""
