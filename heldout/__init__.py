"""A second scene generator, for validation and test only (see ``docs/heldout_world.md``).

It shares no rendering code with ``sim/`` and imports neither ``sim`` nor sarmission's camera or
geolocation code: a detector tuned to one renderer's quirks is measured on another's. Output is
the COCO video layout that ``sarmission eval`` reads (:mod:`heldout.generate`).
"""
