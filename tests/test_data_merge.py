"""Merging annotation files from several folders and renderers into one training or validation
set, and the held-out validation split of the training recipe."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from conftest import load_tool
from synthetic_video import write_dataset

from sarmission.data.coco_video import read_coco_video, write_coco_video
from sarmission.data.merge import merge_annotation_files
from sarmission.data.sequence import iter_sequence

#: An alternative-world land clip with people in view from its first frame (figures start
#: anywhere in the box around the first view's footprint, so some clips open empty).
LAND_SEED_WITH_PEOPLE = 9_320_003


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("merge_data")
    return {
        "train": write_dataset(root / "a", n_videos=1, n_frames=4, seed=1),
        "val": write_dataset(root / "b", n_videos=1, n_frames=5, seed=2),
    }


def test_merge_unites_categories_by_name_and_paths(data, tmp_path) -> None:
    """A land file whose people are ``person`` (and which also lists an unused ``swimmer``)
    merges with a maritime one: people and swimmers are one ``swimmer`` category, paths still
    resolve from another folder."""
    land_doc = json.loads(Path(data["val"]).read_text())
    names = {c["id"]: c["name"] for c in land_doc["categories"]}
    swimmer_id = next(cid for cid, n in names.items() if n == "swimmer")
    for category in land_doc["categories"]:
        if category["id"] == swimmer_id:
            category["name"] = "person"
    land_doc["categories"].append({"id": 99, "name": "swimmer"})
    land = Path(data["val"]).with_name("land.json")
    land.write_text(json.dumps(land_doc))
    merged = merge_annotation_files([data["train"], land], {"person": "swimmer"})
    out = tmp_path / "elsewhere" / "merged.json"
    out.parent.mkdir()
    write_coco_video(merged, out)
    again = read_coco_video(out)
    by_name = {c.name: c.id for c in again.categories}
    assert len(by_name) == len(again.categories)
    assert "person" not in by_name and "swimmer" in by_name
    first, second = (read_coco_video(p) for p in (data["train"], land))
    assert len(again.videos) == 2 and len(again.images) == len(first.images) + len(second.images)
    n_swimmers = sum(a.category_id == swimmer_id for a in first.annotations + second.annotations)
    assert sum(a.category_id == by_name["swimmer"] for a in again.annotations) == n_swimmers
    frames = [item.frame_bgr for video in again.videos for item in iter_sequence(again, video.id)]
    assert len(frames) == len(again.images)
    assert len({im.id for im in again.images}) == len(again.images)


def test_heldout_validation_clips_are_not_test_clips() -> None:
    """The recipe's held-out validation seeds lie outside the clip indices kept for tests
    (tools/heldout_eval.py renders clips 0, 1, 2 ... of each world)."""
    tool = load_tool("train_default_model")
    from heldout.presets import world

    seeds = tool.heldout_val_seeds()
    assert len(seeds) == sum(clips for _, clips, _ in tool.HELDOUT_VAL) == len(set(seeds))
    test_seeds = {
        world(name).seed * 1000 + i
        for name, _, _ in tool.HELDOUT_VAL
        for i in range(tool.HELDOUT_VAL_FIRST_CLIP)
    }
    assert not test_seeds & set(seeds)
    assert tool.HELDOUT_VAL_FIRST_CLIP >= 50


def test_the_recipe_adds_the_alternative_world_with_land_people_as_swimmers(
    data, tmp_path, monkeypatch
) -> None:
    """``--altworld`` renders the alternative world's clips beside the training file and
    merges them: every frame is readable and land people count as ``swimmer``."""
    from altworld.generate import FIRST_SEEDS

    tool = load_tool("train_default_model")
    monkeypatch.setattr(tool, "ALTWORLD_SPLITS", (("sea", 1, 3), ("land", 1, 3)))
    monkeypatch.setitem(FIRST_SEEDS, "land", LAND_SEED_WITH_PEOPLE)
    merged = tool.add_altworld(tmp_path, Path(data["train"]))
    again = read_coco_video(merged)
    names = {c.id: c.name for c in again.categories}
    land = read_coco_video(tmp_path / "altworld" / "altworld_land.json")
    land_names = {c.id: c.name for c in land.categories}
    n_people = sum(land_names[a.category_id] == "person" for a in land.annotations)
    assert n_people > 0 and "person" not in names.values()
    first = read_coco_video(data["train"])
    assert len(again.images) == len(first.images) + 6
    sea_video = next(v for v in again.videos if v.name == "altworld_sea_00")
    assert len(list(iter_sequence(again, sea_video.id))) == 3
    assert tool.add_altworld(tmp_path, Path(data["train"])) == merged  # reused, not redone


def test_the_land_recipe_adds_only_the_alternative_land_with_people_as_person(
    data, tmp_path, monkeypatch
) -> None:
    from altworld.generate import FIRST_SEEDS

    tool = load_tool("train_default_model")
    monkeypatch.setattr(tool, "ALTWORLD_SPLITS", (("sea", 1, 2), ("land", 1, 2)))
    monkeypatch.setitem(FIRST_SEEDS, "land", LAND_SEED_WITH_PEOPLE)
    merged = read_coco_video(tool.add_altworld(tmp_path, Path(data["train"]), ("land",), {}))
    assert [v.name for v in merged.videos if v.name.startswith("altworld")] == ["altworld_land_00"]
    assert not (tmp_path / "altworld" / "altworld_sea.json").exists()
    names = {c.id: c.name for c in merged.categories}
    assert any(names[a.category_id] == "person" for a in merged.annotations)


def test_training_without_ffmpeg_stops_before_rendering_anything(tmp_path, monkeypatch) -> None:
    """The held-out validation clips are H.264: without ffmpeg the recipe says so in one line
    before it renders the (long) training set, for the maritime and the land head."""
    tool = load_tool("train_default_model")
    monkeypatch.setattr("shutil.which", lambda name: None)
    rendered = []
    for name in ("render_training_set", "render_broad_training_set", "render_land_training_set"):
        monkeypatch.setattr(tool, name, lambda *args, _n=name: rendered.append(_n))
    for head in ("maritime", "land"):
        monkeypatch.setattr(sys, "argv", ["x", "--work", str(tmp_path), "--head", head])
        with pytest.raises(SystemExit, match="ffmpeg is not installed") as stop:
            tool.main()
        assert "heldout_" in str(stop.value)
    assert rendered == []


def test_ffmpeg_is_not_needed_once_the_validation_clips_are_there(tmp_path, monkeypatch) -> None:
    tool = load_tool("train_default_model")
    monkeypatch.setattr("shutil.which", lambda name: None)
    assert tool.heldout_val_missing(tmp_path) == [w for w, _, _ in tool.HELDOUT_VAL]
    (tmp_path / "heldout_val" / "heldout_maritime").mkdir(parents=True)
    (tmp_path / "heldout_val" / "heldout_maritime" / "heldout_maritime.json").write_text("{}")
    assert tool.heldout_val_missing(tmp_path) == ["heldout_land"]
    (tmp_path / "heldout_val" / "heldout_val.json").write_text("{}")
    assert tool.heldout_val_missing(tmp_path) == []
    tool.require_ffmpeg_for(tmp_path)  # nothing to render: no ffmpeg needed


def test_a_named_variant_gets_its_own_file(tmp_path, monkeypatch) -> None:
    """``--name`` keeps two variants of one recipe trained in one folder apart."""
    tool = load_tool("train_default_model")
    trained = []
    monkeypatch.setattr(tool, "render_broad_training_set", lambda work, presets: work / "t.json")
    monkeypatch.setattr(tool, "render_heldout_val", lambda work: work / "v.json")
    monkeypatch.setattr(tool, "train_head", lambda t, v, out, *a: trained.append(out.name) or 0)
    for extra in ([], ["--name", "namer_debris"]):
        monkeypatch.setattr(
            sys,
            "argv",
            ["x", "--work", str(tmp_path), "--presets", "buoys", "--seed", "3", "--no-install"]
            + extra,
        )
        assert tool.main() == 0
    assert trained == ["mitenet_head_buoys_seed3.pt", "namer_debris_seed3.pt"]
