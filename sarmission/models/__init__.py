"""The default MITE-Net head shipped with the package (torch weights and ONNX)."""

from __future__ import annotations

from pathlib import Path

from sarmission.errors import SarmissionError

MODEL_DIR = Path(__file__).resolve().parent
DEFAULT_TORCH_MODEL = MODEL_DIR / "mitenet_head.pt"
DEFAULT_ONNX_MODEL = MODEL_DIR / "mitenet_head.onnx"


def default_model_path(runtime: str = "torch") -> Path:
    """Path of the shipped default head for ``runtime`` ("torch" or "onnx").

    Raises ``SarmissionError`` when the package was installed without its model files.
    """
    path = DEFAULT_ONNX_MODEL if runtime == "onnx" else DEFAULT_TORCH_MODEL
    if not path.is_file():
        raise SarmissionError(
            f"no default model at {path}; pass --model PATH (train one with `sarmission train`)"
        )
    return path
