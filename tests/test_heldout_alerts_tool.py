"""``tools/heldout_alerts.py``: a replay's stored alerts scored against its clip, the time to
alert taken from the lock frame and the store's lock-to-confirmation interval, candidates
never counted as alerts."""

from __future__ import annotations

import pytest
from conftest import load_tool

from sarmission.alerts.model import Alert
from sarmission.alerts.store import AlertStore
from sarmission.data.coco_video import Annotation, Category, ImageRecord, Video, VideoDataset

FPS = 10.0
EPOCH = 1.7e9


@pytest.fixture(scope="module")
def tool():
    return load_tool("heldout_alerts")


def clip() -> tuple[VideoDataset, Video]:
    """50 frames: a swimmer at (100, 100) from frame 5 on, a rock at (400, 300) throughout."""
    video = Video(1, "clip", {"fps": FPS, "width": 960, "height": 540, "hfov_deg": 30.0})
    images, annotations = [], []
    for k in range(50):
        images.append(ImageRecord(k + 1, f"clip/{k}.jpg", 540, 960, 1, k))
        if k >= 5:
            annotations.append(Annotation(len(annotations) + 1, k + 1, 1, (95, 95, 10, 10), 3, 1))
        annotations.append(Annotation(len(annotations) + 1, k + 1, 2, (390, 290, 20, 20), 4, 1))
    categories = [Category(1, "swimmer"), Category(2, "rock")]
    return VideoDataset([video], images, annotations, categories), video


def alert(target: int, frame: int, x: float, y: float) -> Alert:
    return Alert(
        mission_id="m",
        target_id=target,
        class_name="swimmer",
        score=0.9,
        lock_time=EPOCH + frame / FPS,
        frame_index=frame,
        pixel_track=[(frame, x, y)],
        tier="candidate",
    )


def test_confirmed_alerts_are_scored_and_candidates_are_not(tool, tmp_path) -> None:
    dataset, video = clip()
    db = tmp_path / "a.db"
    with AlertStore(db) as store:
        person = alert(1, 8, 100.0, 100.0)
        rock = alert(2, 9, 400.0, 300.0)
        idle = alert(3, 9, 700.0, 50.0)
        for a in (person, rock, idle):
            store.add(a)
        store.promote(person.alert_id, "seen", when=person.lock_time + 2.0)
        store.promote(rock.alert_id, "seen", when=rock.lock_time + 2.5)
    score = tool.score_clip(dataset, video, db)
    assert score.alerts == 2  # the third stayed a candidate
    assert score.people_in_view == 1 and score.found == 1
    # first seen at frame 5 (0.5 s), locked at 0.8 s, confirmed 2 s later
    assert score.time_to_alert_s == [pytest.approx(2.3)]
    assert score.false_alerts == 1 and dict(score.false_on) == {"rock": 1}
    assert len(score.candidate_scores) == 3


def test_the_replay_gets_the_clips_lens(tool, tmp_path) -> None:
    _, video = clip()
    cmd = tool.replay_command(tmp_path / "c.json", video, tmp_path / "a.db", None, ["a.b=1"])
    sets = [cmd[i + 1] for i, word in enumerate(cmd) if word == "--set"]
    assert sets == ["camera.width=960", "camera.height=540", "camera.hfov_deg=30.0", "a.b=1"]
    assert cmd[cmd.index("--video-id") + 1] == "1" and cmd[cmd.index("--fps") + 1] == "10"


def test_rendering_without_ffmpeg_says_so_before_any_work(tool, tmp_path, monkeypatch) -> None:
    monkeypatch.setattr("shutil.which", lambda name: None)
    rendered = []
    monkeypatch.setattr(tool, "render_clip", lambda *args: rendered.append(args))
    with pytest.raises(SystemExit, match="ffmpeg is not installed"):
        tool.render_clips(tmp_path, ["heldout_maritime"], 50, 2, 30, 1)
    assert rendered == []
    assert not (tmp_path / "heldout_maritime").exists()
