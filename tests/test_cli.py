"""The ``sarmission`` command line end to end: real files through OpenCV, real ONNX files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
from conftest import free_udp_port
from motion_scenes import moving_target, to_bgr

from sarmission.cli import build_parser, main
from sarmission.errors import SarmissionError
from sarmission.perception.head import MiteHead
from sarmission.perception.runtime import save_head_checkpoint

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An untrained head checkpoint (the CLI's behaviour does not depend on the weights)."""
    import torch

    torch.manual_seed(0)
    return save_head_checkpoint(MiteHead().eval(), tmp_path_factory.mktemp("model") / "head.pt")


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short MP4 of a small target moving over a textured background."""
    frames, _ = moving_target(
        240, 320, 12, start=(100.0, 120.0), velocity=(1.5, 0.5), size=8, seed=3
    )
    path = tmp_path_factory.mktemp("video") / "clip.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30, (320, 240))
    for frame in frames:
        writer.write(to_bgr(frame))
    writer.release()
    return path


def test_detect_writes_coco_results_for_every_frame(
    clip: Path, checkpoint: Path, tmp_path: Path
) -> None:
    out = tmp_path / "dets.json"
    code = main(
        [
            "detect",
            str(clip),
            "--model",
            str(checkpoint),
            "--runtime",
            "torch",
            "--ds",
            "2",
            "--topn",
            "10",
            "--conf",
            "0.0",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    records = json.loads(out.read_text())
    assert records, "a zero threshold keeps every proposal the head scores"
    frames = {r["frame_index"] for r in records}
    assert frames <= set(range(12))
    for r in records:
        assert set(r) == {"image_id", "frame_index", "bbox", "score", "category_id"}
        x, y, w, h = r["bbox"]
        assert w > 0 and h > 0 and 0 <= r["score"] <= 1 and r["category_id"] in (1, 2)
    per_frame = np.bincount([r["frame_index"] for r in records])
    assert per_frame.max() <= 10


def test_detect_reports_a_wrong_model_file_in_one_line(
    clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    bogus = tmp_path / "model.pt"
    bogus.write_bytes(b"not a checkpoint at all")
    code = main(["detect", str(clip), "--model", str(bogus), "--out", str(tmp_path / "d.json")])
    err = capsys.readouterr().err
    assert code == 2
    assert "model.pt" in err and "Traceback" not in err
    assert not (tmp_path / "d.json").exists()


def test_detect_reports_a_missing_input(
    tmp_path: Path, checkpoint: Path, capsys: pytest.CaptureFixture
) -> None:
    code = main(["detect", str(tmp_path / "nope.mp4"), "--model", str(checkpoint)])
    assert code == 2
    assert "nope.mp4" in capsys.readouterr().err


def test_export_writes_onnx_that_loads_with_a_dynamic_proposal_axis(
    checkpoint: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "head.onnx"
    assert main(["export", "--model", str(checkpoint), "--out", str(out)]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith(f"wrote {out}: ") and ", opset 17, max |onnx - torch| " in line
    assert float(line.rsplit(" ", 1)[1]) < 1e-4
    model = onnx.load(str(out))
    onnx.checker.check_model(model)
    first_dim = model.graph.input[0].type.tensor_type.shape.dim[0]
    assert first_dim.dim_param, "the proposal axis must be symbolic"
    assert model.opset_import[0].version == 17


def test_export_and_detect_never_write_over_what_they_read(
    checkpoint: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """`export --average a.pt b.pt --out a.onnx` wrote the mean over a.pt; `--out b.pt`
    wrote ONNX over the checkpoint; `detect --out` over its model or annotations. Exit 0."""
    import shutil

    import cv2
    import numpy as np
    import torch

    a, b = tmp_path / "a.pt", tmp_path / "b.pt"
    shutil.copy(checkpoint, a)
    shutil.copy(checkpoint, b)
    before = a.read_bytes()
    cases = [
        (["export", "--average", str(a), str(b), "--out", str(tmp_path / "a.onnx")], "one of"),
        (["export", "--model", str(b), "--out", str(b)], "expected a .onnx file"),
        (["export", "--model", str(b), "--out", str(tmp_path)], "a folder"),
        (["export", "--model", str(b), "--opset", "5", "--out", str(tmp_path / "x.onnx")], "9 to"),
    ]
    for argv, message in cases:
        assert main(argv) == 2, argv
        assert message in capsys.readouterr().err
    assert a.read_bytes() == before and b.read_bytes() == before
    # a diverged head (NaN weights) is not exported: it would detect nothing, silently
    state = torch.load(b, weights_only=True)
    state["state_dict"] = {k: v.float() * float("nan") for k, v in state["state_dict"].items()}
    torch.save(state, tmp_path / "nan.pt")
    out = tmp_path / "nan.onnx"
    assert main(["export", "--model", str(tmp_path / "nan.pt"), "--out", str(out)]) == 2
    assert "weights are not finite" in capsys.readouterr().err and not out.exists()
    frames = tmp_path / "frames"
    frames.mkdir()
    for name in ("f0.png", "f1.png"):
        cv2.imwrite(str(frames / name), np.full((64, 96, 3), 90, np.uint8))
    model = tmp_path / "head.onnx"
    assert main(["export", "--model", str(b), "--out", str(model)]) == 0
    assert main(["detect", str(frames), "--model", str(model), "--out", str(model)]) == 2
    assert "the same file as --model" in capsys.readouterr().err


def test_a_mission_refuses_a_head_that_names_no_person(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """A head of boats alone ran a whole replay, demo or suite and reported 0 alerts."""
    import cv2
    import numpy as np
    import torch

    from sarmission.perception.head import HeadConfig

    torch.manual_seed(0)
    boats = save_head_checkpoint(MiteHead(HeadConfig(classes=("boat",))), tmp_path / "b.pt")
    frames = tmp_path / "frames"
    frames.mkdir()
    cv2.imwrite(str(frames / "f0.png"), np.full((64, 96, 3), 90, np.uint8))
    for argv in (
        ["replay", str(frames), "--model", str(boats)],
        ["demo", "--model", str(boats), "--duration", "1"],
    ):
        assert main(argv) == 2, argv
        assert "the head names no person (boat)" in capsys.readouterr().err


def test_info_reports_head_parameters_and_stage_flops(capsys: pytest.CaptureFixture) -> None:
    assert main(["info", "--size", "1920x1080", "--ds", "2", "--topn", "25", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert 0 < report["parameters"]["head"] < 140_000
    flops = report["flops"]
    assert flops["total"] == pytest.approx(flops["vstmd"] + flops["rpn_other"] + flops["head"])
    assert main(["info", "--size", "1920x1080", "--ds", "4", "--json"]) == 0
    coarser = json.loads(capsys.readouterr().out)["flops"]
    assert coarser["vstmd"] < flops["vstmd"]


def test_bench_prints_a_json_row_per_configuration() -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "sarmission.cli",
            "bench",
            "--size",
            "320x240",
            "--ds",
            "2,4",
            "--topn",
            "10",
            "--frames",
            "2",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert done.returncode == 0, done.stderr
    rows = json.loads(done.stdout)
    assert [(r["ds"], r["topn"]) for r in rows] == [(2, 10), (4, 10)]
    for row in rows:
        assert row["total_ms"] > 0 and row["memory_pass_ms"] > 0 and row["peak_rss_mb"] > 0
        assert set(row["ms"]) == {"vstmd", "colour", "rpn", "crops", "head", "fit"}
        assert row["colour_share"] == 0.4 and row["crop_scales"] == [1.0]  # the defaults
        assert row["fit_boxes"] is True


def test_bench_runs_the_chosen_colour_share_and_crop_scales(
    capsys: pytest.CaptureFixture,
) -> None:
    """In process (the entry point itself is run above): each option reaches the row."""
    common = ["bench", "--size", "320x240", "--ds", "2", "--topn", "10", "--frames", "2", "--json"]
    runs = []
    for extra in (
        ["--crop-scales", "1,2"],
        ["--colour-share", "0", "--crop-scales", "1"],
        ["--crop-scales", "1,2", "--refine-threshold", "0", "--no-fit-boxes"],
    ):
        assert main(common + extra) == 0
        runs.append(json.loads(capsys.readouterr().out)[0])
    assert runs[0]["fit_boxes"] is True and runs[2]["fit_boxes"] is False
    assert runs[1]["colour_share"] == 0.0 and runs[1]["crop_scales"] == [1.0]
    assert runs[0]["crop_scales"] == [1.0, 2.0]
    assert runs[0]["refine_threshold"] == 0.3 and runs[2]["refine_threshold"] == 0.0
    # A second crop scale may refine every proposal: its bound is twice the single.
    assert runs[0]["gflops"]["head"] == pytest.approx(2 * runs[1]["gflops"]["head"], rel=1e-3)


def test_bad_arguments_exit_with_a_message(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["bench", "--size", "big"])
    assert stop.value.code == 2
    assert "WIDTHxHEIGHT" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        # nan once flew for ever, 0 the whole survey, a negative duration nothing with exit 0
        (["demo", "--duration", "nan"], "expected seconds above 0, got 'nan'"),
        (["demo", "--duration", "0"], "expected seconds above 0, got '0'"),
        (["sim", "score", "--seconds", "-5"], "expected seconds above 0"),
        (["replay", "x.mp4", "--duration", "inf"], "expected seconds above 0"),
        (["sim", "vehicle", "--duration", "nan"], "expected seconds above 0"),
        # fps 0 divided by zero, a negative one ran time backwards, a negative seed or start
        # came out as numpy's message after a stray clip was written
        (["sim", "generate", "--fps", "0", "--out", "never"], "frames per second from 0.001"),
        # nan, inf or 1e-300 frames per second were taken: a run that never paced, or that
        # waited for ever for its second frame
        (["replay", "x.mp4", "--fps", "nan"], "frames per second from 0.001 to 1000"),
        (["replay", "x.mp4", "--fps", "1e-300"], "frames per second from 0.001 to 1000"),
        (["run", "--video", "x.mp4", "--fps", "inf"], "frames per second from 0.001 to 1000"),
        (["run", "--frames", "x", "--fps", "1e-300"], "frames per second from 0.001 to 1000"),
        (["demo", "--fps", "nan"], "0 or frames per second from 0.001 to 1000"),
        (["sim", "replay", "x.mp4", "--fps", "inf"], "frames per second from 0.001 to 1000"),
        (["sim", "generate", "--fps", "1e-300", "--out", "never"], "from 0.001 to 1000"),
        (["sim", "generate", "--start", "-100", "--out", "never"], "0 or more"),
        (["sim", "generate", "--seed", "-1", "--out", "never"], "whole number, 0 or more"),
    ],
)
def test_durations_rates_and_seeds_are_numbers_that_make_sense(
    argv: list[str], message: str, capsys: pytest.CaptureFixture
) -> None:
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    assert message in capsys.readouterr().err


def test_detect_rejects_a_colour_share_outside_0_1(
    clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "d.json"
    code = main(["detect", str(clip), "--colour-share", "1.2", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert "--colour-share must be in [0, 1], got 1.2" in err and "Traceback" not in err
    assert not out.exists()


def run_that_fails(tmp_path: Path, *source: str) -> subprocess.CompletedProcess:
    """``sarmission run`` in a process of its own with ``source`` (and its alert store in
    ``tmp_path``), expected to stop before it starts anything."""
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "sarmission.cli",
            "run",
            "--connect",
            f"udp:127.0.0.1:{free_udp_port()}",
            *source,
            "--alerts-db",
            str(tmp_path / "alerts.db"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_run_with_a_missing_camera_fails_in_one_line(tmp_path: Path) -> None:
    index = 99  # no such /dev/video99 on a test machine
    assert not Path(f"/dev/video{index}").exists()
    done = run_that_fails(tmp_path, "--camera", str(index))
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [
        f"sarmission run: error: cannot open camera {index}: no such device "
        f"(/dev/video{index} does not exist)"
    ]
    assert not (tmp_path / "alerts.db").exists()  # nothing was started


def test_run_with_an_unreadable_tak_certificate_in_the_mission_fails_in_one_line(
    tmp_path: Path,
) -> None:
    """The mission file's TAK destination names a client certificate that is not there: one
    line, exit 2, before the simulated vehicle or the alert store is started."""
    mission = tmp_path / "mission.toml"
    missing = tmp_path / "drone.pem"
    mission.write_text(f'[alerts]\ncot = ["tls://127.0.0.1:8089?cert={missing}"]\n')
    done = run_that_fails(tmp_path, "--sim", "--mission", str(mission))
    assert done.returncode == 2, done.stderr
    (line,) = [x for x in done.stderr.splitlines() if "error" in x]
    assert line == (
        f"sarmission run: error: CoT tls://127.0.0.1:8089?cert={missing}: client certificate "
        f"'{missing}': No such file or directory"
    )
    assert "vehicle on" not in done.stderr  # the simulated vehicle never started
    assert not (tmp_path / "alerts.db").exists()


def test_bad_crop_scales_exit_with_a_message(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["detect", "clip.mp4", "--crop-scales", "1,0"])
    assert stop.value.code == 2
    assert "--crop-scales: expected comma-separated numbers in (0, 8]" in capsys.readouterr().err


def test_bad_refine_threshold_exits_with_a_message(capsys: pytest.CaptureFixture) -> None:
    assert main(["bench", "--refine-threshold", "-0.5", "--quick"]) != 0
    assert "--refine-threshold must be in [0, 1], got -0.5" in capsys.readouterr().err


def test_mission_commands_hand_the_crop_options_to_the_detector(tmp_path: Path) -> None:
    """--crop-scales and --refine-threshold override the mission file's [detector] values."""
    from sarmission.commands.mission_options import build_detector, load_mission_from_args

    mission_file = tmp_path / "m.toml"
    mission_file.write_text("[detector]\ncrop_scales = [1.0]\nrefine_threshold = 0.6\n")
    parser = build_parser()
    from_file = parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file)])
    net, _ = build_detector(from_file, load_mission_from_args(from_file))
    assert net.crop_scales == (1.0,) and net.refine_threshold == 0.6
    overridden = parser.parse_args(
        [
            "replay",
            "clip.mp4",
            "--mission",
            str(mission_file),
            "--crop-scales",
            "1,3",
            "--refine-threshold",
            "0",
        ]
    )
    net, _ = build_detector(overridden, load_mission_from_args(overridden))
    assert net.crop_scales == (1.0, 3.0) and net.refine_threshold == 0.0


def test_recentring_comes_from_the_mission_file_or_the_command_line(tmp_path: Path) -> None:
    """[detector] recentre reaches the detector; --recentre / --no-recentre override the file;
    the built-in default is off, as in the shipped missions; detect and eval take the flag."""
    from sarmission.commands.detector_options import build_mitenet
    from sarmission.commands.mission_options import build_detector, load_mission_from_args

    parser = build_parser()
    plain = parser.parse_args(["replay", "clip.mp4"])
    assert build_detector(plain, load_mission_from_args(plain))[0].recentre is False
    mission_file = tmp_path / "m.toml"
    mission_file.write_text("[detector]\nrecentre = true\n")
    from_file = parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file)])
    assert build_detector(from_file, load_mission_from_args(from_file))[0].recentre is True
    off = parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file), "--no-recentre"])
    assert build_detector(off, load_mission_from_args(off))[0].recentre is False
    on = parser.parse_args(["run", "--connect", "udpin:127.0.0.1:1", "--sim", "--recentre"])
    assert build_detector(on, load_mission_from_args(on))[0].recentre is True
    for shipped in ("maritime_demo.toml", "urban_demo.toml"):
        text = (REPO / "missions" / shipped).read_text()
        assert "\nrecentre = false" in text, shipped
    assert build_mitenet(parser.parse_args(["detect", "clip.mp4"])).recentre is False
    assert build_mitenet(parser.parse_args(["detect", "clip.mp4", "--recentre"])).recentre is True
    assert parser.parse_args(["eval", "--annotations", "a.json", "--recentre"]).recentre is True


def test_a_shipped_head_brings_its_own_confirmation_threshold_unless_the_mission_sets_one(
    tmp_path: Path,
) -> None:
    """The land head's scores run lower than the maritime head's: flown without a mission
    threshold, alerts take the land head's (0.55); a mission file or --set that names one
    keeps it, and a model file keeps the mission's, whatever it is."""
    from sarmission.commands.mission_options import build_detector, load_mission_from_args
    from sarmission.mission.config import ConfirmConfig
    from sarmission.models import CONFIRM_MIN_SCORE, DEFAULT_HEAD, shipped_head_path

    assert ConfirmConfig().min_score == CONFIRM_MIN_SCORE[DEFAULT_HEAD]
    parser = build_parser()

    def threshold(*argv: str) -> tuple[float, str]:
        args = parser.parse_args(["replay", "clip.mp4", *argv])
        mission = load_mission_from_args(args)
        _, note = build_detector(args, mission)
        return mission.confirm.min_score, note

    land, note = threshold("--model", "land")
    assert land == CONFIRM_MIN_SCORE["land"] == 0.55
    assert "a mean score of 0.55, the land head's [confirm] min_score" in note
    default, note = threshold()
    assert default == 0.7 and "min_score" not in note
    assert threshold("--model", "land", "--set", "confirm.min_score=0.8")[0] == 0.8
    assert threshold("--model", "maritime")[0] == 0.7
    file_head = shipped_head_path("land", "onnx")
    assert threshold("--model", str(file_head))[0] == 0.7
    in_mission = tmp_path / "land.toml"
    in_mission.write_text('[detector]\nmodel = "land"\n')
    assert threshold("--mission", str(in_mission))[0] == 0.55
    own = tmp_path / "own.toml"
    own.write_text('[detector]\nmodel = "land"\n[confirm]\nmin_score = 0.7\n')
    assert threshold("--mission", str(own))[0] == 0.7
    shipped = parser.parse_args(
        ["replay", "clip.mp4", "--mission", str(REPO / "missions" / "urban_demo.toml")]
    )
    assert load_mission_from_args(shipped).confirm.min_score == CONFIRM_MIN_SCORE["land"]


def test_orientations_come_from_the_mission_file_or_the_command_line(tmp_path: Path) -> None:
    """[detector] orientations reaches the detector and --orientations overrides it; 1 (a
    single look) is the built-in default; counts other than 1, 4, 8 are refused in one line."""
    from sarmission.commands.detector_options import build_mitenet
    from sarmission.commands.mission_options import build_detector, load_mission_from_args

    parser = build_parser()
    plain = parser.parse_args(["replay", "clip.mp4"])
    assert build_detector(plain, load_mission_from_args(plain))[0].orientations == 1
    mission_file = tmp_path / "m.toml"
    mission_file.write_text("[detector]\norientations = 8\n")
    from_file = parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file)])
    assert build_detector(from_file, load_mission_from_args(from_file))[0].orientations == 8
    cli = parser.parse_args(
        ["replay", "clip.mp4", "--mission", str(mission_file), "--orientations", "4"]
    )
    assert build_detector(cli, load_mission_from_args(cli))[0].orientations == 4
    assert (
        build_mitenet(parser.parse_args(["detect", "clip.mp4", "--orientations", "8"])).orientations
        == 8
    )
    assert (
        parser.parse_args(["eval", "--annotations", "a.json", "--orientations", "4"]).orientations
        == 4
    )
    mission_file.write_text("[detector]\norientations = 3\n")
    with pytest.raises(SarmissionError, match="orientations: expected one of 1, 4, 8"):
        load_mission_from_args(
            parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file)])
        )
    with pytest.raises(SystemExit):
        parser.parse_args(["detect", "clip.mp4", "--orientations", "2"])


def test_the_mission_file_chooses_the_head_and_the_command_line_wins(tmp_path: Path) -> None:
    """[detector] model is read relative to the mission file; --model overrides it; a missing
    file is one clear error naming the resolved path."""
    import shutil

    from sarmission.commands.mission_options import build_detector, load_mission_from_args
    from sarmission.models import DEFAULT_ONNX_MODEL
    from sarmission.perception.runtime import ModelLoadError

    (tmp_path / "heads").mkdir()
    area_head = tmp_path / "heads" / "area.onnx"
    shutil.copyfile(DEFAULT_ONNX_MODEL, area_head)
    mission_file = tmp_path / "m.toml"
    mission_file.write_text('[detector]\nmodel = "heads/area.onnx"\n')
    parser = build_parser()
    args = parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file)])
    _, note = build_detector(args, load_mission_from_args(args))
    assert note == (
        f"model: {area_head} (the mission's [detector] model); "
        "alert confidence: none fitted for area.onnx (its score only)"
    )
    other = tmp_path / "other.onnx"
    shutil.copyfile(DEFAULT_ONNX_MODEL, other)
    args = parser.parse_args(
        ["replay", "clip.mp4", "--mission", str(mission_file), "--model", str(other)]
    )
    _, note = build_detector(args, load_mission_from_args(args))
    assert note.startswith(f"model: {other}; alert confidence: none fitted")
    area_head.unlink()
    args = parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file)])
    with pytest.raises(ModelLoadError, match=f"'{area_head}': file not found"):
        build_detector(args, load_mission_from_args(args))
    args = parser.parse_args(["replay", "clip.mp4"])
    _, note = build_detector(args, load_mission_from_args(args))
    assert note.startswith("model: the shipped default")
    # shipped beside the maritime head, calibrated per mission (docs/confidence_adaptation.md)
    assert note.endswith(
        "; alert confidence: mitenet_head.confidence.json, its level learnt from the "
        "operator's decisions"
    )


def test_a_mission_names_a_shipped_head_by_name(tmp_path: Path) -> None:
    """``[detector] model = "land"`` loads the shipped land head (never a file named "land" next
    to the mission); ``--model maritime`` wins over it; an unknown name is one clear error."""
    from sarmission.commands.mission_options import build_detector, load_mission_from_args
    from sarmission.mission.config import MissionConfigError

    mission_file = tmp_path / "m.toml"
    mission_file.write_text('[detector]\nmodel = "land"\n')
    parser = build_parser()
    args = parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file)])
    mission = load_mission_from_args(args)
    assert mission.detector.model == "land"
    detector, note = build_detector(args, mission)
    assert note.startswith("model: land (the mission's [detector] model); alert confidence")
    assert detector.classes == ("person",)
    args = parser.parse_args(
        ["replay", "clip.mp4", "--mission", str(mission_file), "--model", "maritime"]
    )
    detector, _ = build_detector(args, load_mission_from_args(args))
    assert detector.classes == ("swimmer", "swimmer_with_life_jacket")
    mission_file.write_text('[detector]\nmodel = "sea"\n')
    args = parser.parse_args(["replay", "clip.mp4", "--mission", str(mission_file)])
    with pytest.raises(MissionConfigError, match='model: expected "default", "maritime", "land"'):
        load_mission_from_args(args)


@pytest.mark.parametrize("url", ["http://tak:8087", "udp://tak"])
def test_run_refuses_a_mistyped_cot_destination_before_starting(
    url: str, capsys: pytest.CaptureFixture
) -> None:
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["run", "--connect", "udp:127.0.0.1:1", "--sim", "--cot", url])
    assert stop.value.code == 2
    assert "must be udp://host:port, tcp://host:port or tls://" in capsys.readouterr().err
    args = build_parser().parse_args(
        ["run", "--connect", "udp:127.0.0.1:1", "--sim", "--cot", "udp://239.2.3.1:6969"]
    )
    assert args.cot == ["udp://239.2.3.1:6969"]


def test_detector_flags_set_every_option_of_the_cascade():
    """`detect` and `eval` (a single run and a sweep) build MiteNet from one list of the detector
    flags: every option apart from the head, ds, N and those no flag sets is in it, with the
    flag's value."""
    import inspect

    from sarmission.commands.detector_options import detector_settings
    from sarmission.perception.mitenet import MiteNet

    not_flags = {"self", "head_runtime", "ds", "topn", "target_size", "box_size", "classes"}
    not_flags |= {"nms_iou"}
    # acts only with a pose per frame: eval's --person-m group and the missions set it
    not_flags |= {"range_shift_per_octave"}
    options = set(inspect.signature(MiteNet.__init__).parameters) - not_flags
    argv = ["eval", "--annotations", "a.json", "--no-fit-boxes", "--crop-scales", "1,2"]
    argv += ["--recentre", "--orientations", "4", "--conf", "0.4", "--ego-motion", "none"]
    settings = detector_settings(build_parser().parse_args(argv))
    assert set(settings) == options
    assert settings["fit_boxes"] is False and settings["recentre"] is True
    assert settings["crop_scales"] == (1.0, 2.0) and settings["orientations"] == 4
    assert settings["score_threshold"] == 0.4 and settings["ego_motion"] == "none"
    with pytest.raises(ValueError, match="colour"):
        detector_settings(build_parser().parse_args(argv + ["--colour-share", "2"]))
