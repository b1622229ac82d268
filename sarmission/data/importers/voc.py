"""Pascal VOC annotations (one XML file per image), as LADD and HERIDAL publish them.

Each ``*.xml`` under the dataset folder describes one image: ``<filename>``, ``<size>`` (width,
height; read from the image when missing or zero) and ``<object>`` entries with ``<name>``,
``<bndbox>`` (``xmin ymin xmax ymax``, 1-based pixels in the VOC convention) and
``<difficult>`` (1: stored as an ignore region). The image is looked up by its file name
anywhere under the folder, else by the XML's stem with an image extension; of several images
of that name (``trainImages/IMG_1.JPG`` and ``testImages/IMG_1.JPG``) the one nearest the XML
in the folder tree, and none (skipped, counted) when two are equally near. A split is chosen
by ``ImageSets/Main/<split>.txt`` where the dataset has one, else by a folder whose name starts
with the split's name (``train`` picks ``trainImages/``).
"""

from __future__ import annotations

import logging
import sys
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

from sarmission.data.coco_video import DatasetFormatError, VideoDataset
from sarmission.data.importers.builder import DatasetBuilder, image_size

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff")


def image_index(root: Path) -> dict[str, list[Path]]:
    """Image files under ``root`` by lower-case file name and by lower-case stem."""
    index: dict[str, list[Path]] = {}
    for path in sorted(root.rglob("*")):
        if path.suffix.lower() in IMAGE_SUFFIXES and path.is_file():
            index.setdefault(path.name.lower(), []).append(path)
            if path.stem.lower() != path.name.lower():
                index.setdefault(path.stem.lower(), []).append(path)
    return index


def nearest_image(candidates: list[Path], xml: Path) -> tuple[Path | None, str]:
    """``(image, "")``: the candidate sharing the longest folder prefix with ``xml`` (the
    image beside it, or under the same split's folder); ``(None, why)`` when there is none or
    two are equally near: a name that exists in two splits is never paired by chance."""
    if not candidates:
        return None, "not found"

    def shared(path: Path) -> int:
        n = 0
        for a, b in zip(path.parent.parts, xml.parent.parts, strict=False):
            if a != b:
                break
            n += 1
        return n

    ranked = sorted(candidates, key=shared, reverse=True)
    if len(ranked) > 1 and shared(ranked[0]) == shared(ranked[1]):
        return None, f"ambiguous: {ranked[0]} and {ranked[1]}"
    return ranked[0], ""


def _list_id(entry: str) -> str:
    """A split list's entry as an id: ``a.jpg`` -> ``a``; ``a`` and ``a.b`` as they are."""
    path = Path(entry)
    return path.stem if path.suffix.lower() in IMAGE_SUFFIXES else entry


def _split_files(root: Path, xmls: list[Path], split: str | None) -> list[Path]:
    if split is None:
        return xmls
    listed = root / "ImageSets" / "Main" / f"{split}.txt"
    if listed.is_file():
        lines = listed.read_text(encoding="utf-8-sig").splitlines()  # saved on Windows: BOM
        # ids, as VOC lists them; an image's file name (a.jpg) is taken for its id
        wanted = {_list_id(line.split()[0]) for line in lines if line.strip()}
        return [x for x in xmls if x.stem in wanted]
    chosen = [
        x
        for x in xmls
        if any(part.lower().startswith(split.lower()) for part in x.relative_to(root).parts[:-1])
    ]
    if not chosen:
        folders = sorted({x.relative_to(root).parts[0] for x in xmls if len(x.parts) > 1})
        raise DatasetFormatError(
            f"{root}: no split {split!r} (no ImageSets/Main/{split}.txt and no folder named "
            f"{split}...; folders: {', '.join(folders) or 'none'})"
        )
    return chosen


def _number(node: ET.Element, tag: str, where: str) -> float:
    text = node.findtext(tag)
    try:
        return float(text) if text is not None else float("nan")
    except ValueError:
        raise DatasetFormatError(f"{where}: <{tag}> is {text!r}, not a number") from None


def import_voc(
    root: Path,
    *,
    source: str,
    licence: str,
    category: Callable[[str], str | None],
    split: str | None = None,
    progress: bool = True,
) -> VideoDataset:
    """Read every VOC XML under ``root`` (module docstring). ``category`` maps a VOC class
    name to the project's (None: the object is not kept)."""
    from tqdm import tqdm

    if not root.is_dir():
        raise DatasetFormatError(f"{root}: not a folder")
    xmls = sorted(root.rglob("*.xml"))
    if not xmls:
        raise DatasetFormatError(f"{root}: no Pascal VOC .xml annotation found")
    xmls = _split_files(root, xmls, split)
    images = image_index(root)
    out = DatasetBuilder(source, licence)
    for xml in tqdm(xmls, desc=source, unit="image", file=sys.stderr, disable=not progress):
        try:
            doc = ET.parse(xml).getroot()
        except ET.ParseError as exc:
            raise DatasetFormatError(f"{xml}: not valid XML ({exc})") from None
        name = (doc.findtext("filename") or "").strip()
        found = images.get(Path(name).name.lower(), []) if name else []
        path, why = nearest_image(found or images.get(xml.stem.lower(), []), xml)
        if path is None:
            out.skipped["no image file" if why == "not found" else "image name ambiguous"] += 1
            log.warning("%s: its image %s: %s under %s", xml, name or xml.stem, why, root)
            continue
        size = doc.find("size")
        width = _number(size, "width", str(xml)) if size is not None else 0.0
        height = _number(size, "height", str(xml)) if size is not None else 0.0
        if not (width > 0 and height > 0):
            width, height = image_size(path)
        image_id = out.image(path, int(width), int(height))
        for obj in doc.iter("object"):
            label = category((obj.findtext("name") or "").strip())
            if label is None:
                out.skipped["class not kept"] += 1
                continue
            box = obj.find("bndbox")
            if box is None:
                raise DatasetFormatError(f"{xml}: an <object> without <bndbox>")
            x0, y0, x1, y1 = (_number(box, t, str(xml)) for t in ("xmin", "ymin", "xmax", "ymax"))
            difficult = (obj.findtext("difficult") or "0").strip() == "1"
            out.box(
                image_id, label, x0 - 1.0, y0 - 1.0, x1 - x0 + 1.0, y1 - y0 + 1.0, ignore=difficult
            )
    return out.build()
