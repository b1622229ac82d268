"""An alternative training world (see ``docs/altworld.md``).

A third renderer beside ``sim/`` (training) and ``heldout/`` (validation and test): written from
its own description, it imports neither of them nor ``sarmission``, so a head trained on both
``sim/`` and this world cannot lean on one renderer's quirks. Output is the COCO video layout that
``sarmission train`` reads (:mod:`altworld.generate`).
"""
