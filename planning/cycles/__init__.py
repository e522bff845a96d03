"""Work cycles: a whole job of a machine in one plan.

A drilling round of a jumbo's booms (``round``), a pallet filled by a palletizer
(``pallet``) and a pile plan driven by a piling rig (``piles``). Each builds on the motion
layer below it: Cartesian lines for feeds, lifts and mast lowering, carried loads, held
orientations, and the hydraulic timing of the trajectories layer. Import the modules
themselves (``planning.cycles.round``, ...); this package exports nothing of its own.
"""
