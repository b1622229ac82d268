"""The MITE-Net heads shipped with the package (torch weights and ONNX), by name.

``maritime`` (the default; also what ``default`` means) has the classes ``swimmer`` and
``swimmer_with_life_jacket`` and was trained on sea and land alike; ``land`` (class ``person``)
is fine-tuned from it on the simulator's land (docs/land_head.md). A mission's ``[detector]
model`` and every ``--model`` take either name or a model file.
"""

from __future__ import annotations

from pathlib import Path

from sarmission.errors import SarmissionError

MODEL_DIR = Path(__file__).resolve().parent
#: Shipped head name -> file stem in :data:`MODEL_DIR` (``.pt`` and ``.onnx``).
SHIPPED_HEADS: dict[str, str] = {"maritime": "mitenet_head", "land": "mitenet_land_head"}
#: The head used when none is named, and the name that means it whichever it is.
DEFAULT_HEAD = "maritime"
DEFAULT_NAME = "default"
#: Shipped head name -> the ``[confirm] min_score`` chosen with its scores on held-out
#: validation clips (maritime: docs/experiments.md; land: docs/land_head.md). A mission that
#: does not set ``min_score`` takes its head's.
CONFIRM_MIN_SCORE: dict[str, float] = {"maritime": 0.7, "land": 0.55}


def shipped_checkpoint(name: str) -> Path:
    """Where the shipped head ``name`` (a key of :data:`SHIPPED_HEADS`) keeps its ``.pt``; its
    ``.onnx`` sits beside it. Whether the file exists is not checked."""
    return MODEL_DIR / f"{SHIPPED_HEADS[name]}.pt"


DEFAULT_TORCH_MODEL = shipped_checkpoint(DEFAULT_HEAD)
DEFAULT_ONNX_MODEL = DEFAULT_TORCH_MODEL.with_suffix(".onnx")


def is_head_name(model: str | Path) -> bool:
    """True when ``model`` names a shipped head (or ``default``) rather than a file."""
    return isinstance(model, str) and (model in SHIPPED_HEADS or model == DEFAULT_NAME)


def shipped_head_path(name: str, runtime: str = "torch") -> Path:
    """The file of the shipped head ``name`` for ``runtime`` ("torch" or "onnx"; the ``.pt``
    when the package has no ``.onnx`` of it). ``SarmissionError`` for an unknown name or a
    package installed without that head's files."""
    if name == DEFAULT_NAME:
        name = DEFAULT_HEAD
    if name not in SHIPPED_HEADS:
        raise SarmissionError(
            f"no shipped head named {name!r}; expected one of {', '.join(SHIPPED_HEADS)} "
            "or a .pt/.onnx file"
        )
    torch_path = shipped_checkpoint(name)
    onnx_path = torch_path.with_suffix(".onnx")
    for path in (onnx_path, torch_path) if runtime == "onnx" else (torch_path,):
        if path.is_file():
            return path
    raise SarmissionError(
        f"the package has no {name} head at {torch_path}; pass --model PATH "
        "(train one with `sarmission train`)"
    )


def default_model_path(runtime: str = "torch") -> Path:
    """Path of the shipped default head for ``runtime`` ("torch" or "onnx"):
    :func:`shipped_head_path` of ``default``.

    Raises ``SarmissionError`` when the package was installed without its model files.
    """
    return shipped_head_path(DEFAULT_NAME, runtime)


def shipped_min_score(model: str | Path | None) -> tuple[str, float] | None:
    """The shipped head ``model`` names (None: the default) and its confirmation threshold
    (:data:`CONFIRM_MIN_SCORE`); None for a model file, whose threshold is unknown."""
    if model is None or model == DEFAULT_NAME:
        model = DEFAULT_HEAD
    if not isinstance(model, str) or model not in CONFIRM_MIN_SCORE:
        return None
    return model, CONFIRM_MIN_SCORE[model]
