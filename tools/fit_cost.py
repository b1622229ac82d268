"""What fitting boxes to the object costs per 4K frame, measured side by side in one process.

``sarmission bench`` times each configuration in its own process, and on a shared 2-core
machine two processes a minute apart differ by more than the fitting costs. Here one detector
(ds 2, N 25, every default) runs the benchmark's synthetic frames with ``fit_boxes`` on and
off in alternating blocks of ten frames, so both see the same frames, clock and neighbours.
Prints the medians per frame, their ratio and the fit stage's own median, as a markdown table.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # runnable from a checkout that is not installed
    sys.path.insert(0, str(ROOT))

from sarmission.threads import apply_thread_plan  # noqa: E402

#: Frames per block of one setting; the first two of each block are not timed (warm-up).
BLOCK = 10
SKIPPED_PER_BLOCK = 2


def measure(blocks: int, frames: int, width: int, height: int) -> dict[bool, dict[str, float]]:
    """Median frame and fit-stage ms with fitting on (True) and off, over ``blocks`` blocks."""
    from sarmission.benchmark import synthetic_frames
    from sarmission.perception.mitenet import MiteNet, build_head_runtime

    images = synthetic_frames(width, height, frames)
    net = MiteNet(build_head_runtime(None, "onnx"), ds=2, topn=25, fit_boxes=True)
    totals: dict[bool, list[float]] = {True: [], False: []}
    fitting: dict[bool, list[float]] = {True: [], False: []}
    index = 0
    for block in range(blocks):
        net.fit_boxes = block % 2 == 0
        for k in range(BLOCK):
            start = time.perf_counter()
            net.process(images[index % len(images)], index / 30.0)
            elapsed = (time.perf_counter() - start) * 1e3
            index += 1
            if block >= 2 and k >= SKIPPED_PER_BLOCK:  # the first two blocks warm up
                totals[net.fit_boxes].append(elapsed)
                fitting[net.fit_boxes].append(net.per_stage_ms.get("fit", 0.0))
    return {
        on: {
            "frame_ms": statistics.median(totals[on]),
            "fit_ms": statistics.median(fitting[on]),
            "frames": len(totals[on]),
        }
        for on in (True, False)
    }


def table(result: dict[bool, dict[str, float]]) -> str:
    """The markdown table of :func:`measure`'s result."""
    on, off = result[True], result[False]
    ratio = on["frame_ms"] / off["frame_ms"]
    return "\n".join(
        [
            "| boxes | frame ms (median) | fit stage ms | frames | ratio to head's boxes |",
            "|---|---|---|---|---|",
            f"| fitted | {on['frame_ms']:.2f} | {on['fit_ms']:.2f} | {on['frames']:.0f} "
            f"| {ratio:.3f} |",
            f"| head's | {off['frame_ms']:.2f} | {off['fit_ms']:.2f} | {off['frames']:.0f} | 1 |",
        ]
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=24, help="blocks of 10 frames (even)")
    parser.add_argument("--frames", type=int, default=20, help="distinct frames, reused")
    parser.add_argument("--size", default="3840x2160", help="WIDTHxHEIGHT")
    parser.add_argument("--repeats", type=int, default=3, help="measurements, each printed")
    args = parser.parse_args(argv)
    if args.blocks < 4 or args.blocks % 2:
        parser.error("--blocks must be even and at least 4")
    width, height = (int(v) for v in args.size.lower().split("x"))
    apply_thread_plan()
    for repeat in range(args.repeats):
        print(f"\nrun {repeat + 1} of {args.repeats}")
        print(table(measure(args.blocks, args.frames, width, height)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
