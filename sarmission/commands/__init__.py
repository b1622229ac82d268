"""Sub-commands of the ``sarmission`` CLI; each module has ``add_parser`` and a ``run`` function.

Heavy imports (torch, OpenCV, pymavlink) happen inside ``run`` so ``sarmission --help`` is fast.
"""

from sarmission.commands import (
    bench,
    data,
    demo,
    detect,
    eval,
    export,
    info,
    replay,
    run,
    sim,
    train,
)

COMMANDS = (info, detect, train, eval, bench, export, data, sim, run, replay, demo)
