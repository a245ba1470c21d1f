"""Offline analysis on top of the physics, not used by the environments or the gap workflow.

* :mod:`.reference`: the independent validation integrator (scipy Radau) of the same equations.
* :mod:`.max_force`: the largest force static friction can hold, per direction.
"""
