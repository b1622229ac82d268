"""Frame-to-alert latency on a live stream, written to docs/benchmarks.md.

``ffmpeg`` sends the simulator's 4K maritime_test clip (from ``tools/pipeline_benchmark.py``),
re-encoded as a camera streams it (H.264 at 20 Mb/s without B-frames, at each of ``--rates``
frames/s), as MPEG-TS over UDP to 127.0.0.1 in real time. The receiving side is what
``sarmission run --video udp://...`` runs: the stream source (decoding in its own thread, newest
frame first), MITE-Net and the mission controller, with the clip's own per-frame telemetry
(dataset ``meta``) pushed at each frame's capture time.

Per processed frame: the latency from its capture stamp (the stream's presentation time on the
local clock, anchored to the least-delayed decoded frame, so the camera's encoding and the
network's minimum delay come on top) to the controller's result; per alert: from the capture
stamp of the frame that confirmed it to the alert leaving the controller. Also frames received,
processed, dropped (a busy detector takes the newest frame), not decoded (the reader skipping
to the next keyframe when it falls behind the camera) and lost.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from pipeline_benchmark import DOC, machine_busy_s, make_clip, write_section  # noqa: E402

from sarmission.commands.cli_helpers import free_udp_port  # noqa: E402

BEGIN_TAG = "stream_latency"
CLIP_FPS = 30.0  # the rendered clip's rate: its telemetry is per frame of it


def own_cpu_s() -> float:
    """CPU seconds of this process and its finished children (the sender)."""
    me, children = (
        resource.getrusage(who) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
    )
    return me.ru_utime + me.ru_stime + children.ru_utime + children.ru_stime


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def stream_clip(work: Path, frames: int, rate: int) -> Path:
    """The benchmark clip as a camera streams it: 20 Mb/s, no B-frames, ``rate`` frames/s (every
    frame of the 30 frames/s clip, or every second or third; cached)."""
    path = work / f"maritime_test_{frames}_stream20M_{rate}fps.mp4"
    if not path.is_file():
        subprocess.run(
            [
                shutil.which("ffmpeg") or "ffmpeg",
                "-loglevel",
                "error",
                "-y",
                "-i",
                str(make_clip(work, frames)),
                "-r",
                str(rate),
                "-c:v",
                "libx264",
                "-preset",
                "veryfast",
                "-tune",
                "zerolatency",
                "-b:v",
                "20M",
                "-maxrate",
                "20M",
                "-bufsize",
                "20M",
                "-bf",
                "0",
                "-g",
                str(rate),
                "-pix_fmt",
                "yuv420p",
                str(path),
            ],
            check=True,
        )
    return path


def measure(clip: Path, annotations: Path) -> dict:
    from sarmission.alerts.store import AlertStore
    from sarmission.data.coco_video import read_coco_video
    from sarmission.data.meta_conventions import MetaPose, dataset_conventions, meta_pose
    from sarmission.data.stream import StreamSource
    from sarmission.mission.config import load_mission
    from sarmission.mission.controller import MissionController
    from sarmission.mission.live import telemetry_buffer
    from sarmission.mission.replay_telemetry import push_frame_telemetry
    from sarmission.perception.mitenet import MiteNet, build_head_runtime
    from sarmission.threads import apply_thread_plan

    apply_thread_plan()
    dataset = read_coco_video(annotations)
    conventions = dataset_conventions(dataset)
    meta = {im.frame_index: meta_pose(im.telemetry, conventions) for im in dataset.images}
    mission = load_mission()
    d = mission.detector
    detector = MiteNet(
        build_head_runtime(None, "onnx"),
        ds=d.ds,
        topn=d.topn,
        score_threshold=d.score_threshold,
        colour_share=d.colour_share,
        crop_scales=tuple(d.crop_scales),
        refine_threshold=d.refine_threshold,
    )
    port = free_udp_port()
    url = f"udp://127.0.0.1:{port}"
    opened: dict[str, object] = {}

    def open_source() -> None:  # binds the port at once, then waits for the first frame
        try:
            opened["source"] = StreamSource(url, connect_timeout_s=30.0)
        except Exception as exc:  # reported below
            opened["error"] = exc

    opener = threading.Thread(target=open_source)
    opener.start()
    time.sleep(1.0)  # the receiver listens before the camera starts: it sees the first frame
    sender = subprocess.Popen(
        [
            shutil.which("ffmpeg") or "ffmpeg",
            "-loglevel",
            "error",
            "-re",
            "-i",
            str(clip),
            "-c",
            "copy",
            "-f",
            "mpegts",
            f"{url}?pkt_size=1316",
        ],
        stdin=subprocess.DEVNULL,
    )
    opener.join()
    if "error" in opened:
        sender.kill()
        raise SystemExit(f"no stream: {opened['error']}")
    source = opened["source"]
    frame_latency, alert_latency, processed, last = [], [], 0, -1
    busy, own, started = machine_busy_s(), own_cpu_s(), time.perf_counter()
    lines: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        store = AlertStore(Path(tmp) / "alerts.db")
        buffer = telemetry_buffer(mission)
        controller = MissionController(mission, detector, buffer, store, console=lines.append)
        try:
            while True:
                frame = source.read()
                if frame is None or (frame.image is None and sender.poll() is not None):
                    break
                if frame.image is None:
                    continue
                index = round((frame.stream_time_s or 0.0) * CLIP_FPS)
                if index <= last:  # a restarted stream: the clip's frame cannot be told
                    continue
                last = index
                if isinstance(meta.get(index), MetaPose):
                    push_frame_telemetry(buffer, frame.timestamp_s, meta[index])
                alerts = controller.process(index, frame.timestamp_s, frame.image)
                done = time.monotonic()
                processed += 1
                frame_latency.append(done - frame.timestamp_s)
                alert_latency += [done - frame.timestamp_s] * len(alerts)
        finally:
            sender.kill()
            sender.wait()
            source.close()
            store.close()
    elapsed = time.perf_counter() - started
    others = (machine_busy_s() - busy - (own_cpu_s() - own)) / elapsed
    return {
        "received": source.received,
        "dropped": source.dropped,
        "behind": source.behind,
        "lost": source.lost,
        "processed": processed,
        "frame_latency": frame_latency,
        "alert_latency": alert_latency,
        "fps": source.fps,
        "others": max(0.0, others),
    }


def render(result: dict, clip: Path) -> str:
    """The Markdown lines of one run."""
    frames, alerts = result["frame_latency"], result["alert_latency"]

    def stats(values: list[float]) -> str:
        if not values:
            return "none"
        return (
            f"median {statistics.median(values) * 1e3:.0f} ms, 90th percentile "
            f"{percentile(values, 0.9) * 1e3:.0f} ms, max {max(values) * 1e3:.0f} ms "
            f"({len(values)})"
        )

    return "\n".join(
        [
            f"**{result['fps']:g} frames/s** (`{clip.name}`; other processes kept "
            f"{result['others']:.2f} cores busy meanwhile):",
            "",
            f"- frames: {result['received']} received, {result['processed']} processed, "
            f"{result['dropped']} dropped while the detector was busy (the newest frame wins), "
            f"{result['behind']} not decoded to keep up with the camera, "
            f"{result['lost']} lost on the way",
            f"- capture to controller result, per processed frame: {stats(frames)}",
            f"- capture of the confirming frame to the alert: {stats(alerts)}",
        ]
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "sar-bench")
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument(
        "--rates",
        default="10,30",
        help="stream frame rates to measure, comma-separated (default: 10,30)",
    )
    parser.add_argument("--out", type=Path, default=DOC)
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    annotations = args.work / f"maritime_test_{args.frames}.json"
    parts = [
        f"Measured {time.strftime('%Y-%m-%d')} with `python tools/stream_latency.py` "
        f"({os.cpu_count()} cores): the 4K maritime_test clip re-encoded as a camera streams it "
        "(H.264, 20 Mb/s, no B-frames) and sent by ffmpeg as MPEG-TS over UDP on 127.0.0.1 in "
        "real time, read by the stream source, MITE-Net (ds 2, N 25) and the mission "
        "controller with the clip's telemetry. Capture is the frame's stamp: the stream's "
        "presentation time on the local clock, anchored to the least-delayed decoded frame; a "
        "camera's encoder and the radio link add their own delay before that."
    ]
    for rate in (int(v) for v in args.rates.split(",")):
        clip = stream_clip(args.work, args.frames, rate)
        parts += ["", render(measure(clip, annotations), clip)]
    report = "\n".join(parts)
    write_section(args.out, report, BEGIN_TAG)
    print(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
