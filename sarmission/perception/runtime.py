"""Head runtimes (torch and onnxruntime) behind one interface, and model-file loading.

Checkpoint format (``.pt``, read with ``torch.load(weights_only=True)``)::

    {"format": "sarmission.mite_head", "format_version": 1,
     "config": HeadConfig.to_dict(),           # classes, reg_max, widths, ...
     "state_dict": MiteHead.state_dict()}

ONNX format (``.onnx``): input ``crops`` ``[N, 4, S, S]`` float32 with a symbolic ``N``; outputs
``cls_logits`` ``[N, C]`` and ``ltrb`` ``[N, 4]``; ``metadata_props`` hold ``sarmission.format``,
``sarmission.format_version`` and ``sarmission.config`` (the same config dict as JSON).

Every failure to read a model raises :class:`ModelLoadError` naming the file and the problem.

torch is imported only by what needs it (checkpoints, :class:`TorchHeadRuntime`): running an ONNX
head loads onnxruntime alone, which keeps a detecting process a few hundred MB smaller. An ONNX
file is checked from the metadata and signature onnxruntime reads, without the ``onnx`` package.
"""

from __future__ import annotations

import json
import sys
from abc import ABC, abstractmethod
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from sarmission.errors import SarmissionError
from sarmission.perception.head_config import HeadConfig

if TYPE_CHECKING:
    from torch import Tensor

    from sarmission.perception.head import MiteHead

MODEL_FORMAT = "sarmission.mite_head"
FORMAT_VERSION = 1
INPUT_NAME = "crops"
OUTPUT_NAMES = ("cls_logits", "ltrb")
META_FORMAT = "sarmission.format"
META_VERSION = "sarmission.format_version"
META_CONFIG = "sarmission.config"
TORCH_SUFFIXES = (".pt", ".pth")
ONNX_SUFFIXES = (".onnx",)


class ModelLoadError(ValueError):
    """A model file is missing, unreadable or not a MITE-Net head of a supported format."""


def _fail(path: Path | str, what: str) -> ModelLoadError:
    return ModelLoadError(f"cannot load head model '{path}': {what}")


def _config_from(path: Path | str, raw: object) -> HeadConfig:
    if not isinstance(raw, dict):
        raise _fail(path, f"config must be a dict, got {type(raw).__name__}")
    try:
        return HeadConfig.from_dict(raw)
    except (TypeError, ValueError) as exc:
        raise _fail(path, f"invalid head config ({exc})") from exc


def _check_version(path: Path | str, fmt: object, version: object) -> None:
    if fmt != MODEL_FORMAT:
        raise _fail(
            path, f"not a sarmission head model (format {fmt!r}, expected {MODEL_FORMAT!r})"
        )
    if not isinstance(version, int) or not 1 <= version <= FORMAT_VERSION:
        raise _fail(
            path, f"unsupported format version {version!r} (this build reads 1..{FORMAT_VERSION})"
        )


def save_head_checkpoint(model: MiteHead, path: str | Path) -> Path:
    """Write ``model`` in the checkpoint format above; returns the path."""
    import torch

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(
        {
            "format": MODEL_FORMAT,
            "format_version": FORMAT_VERSION,
            "config": model.config.to_dict(),
            "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        },
        path,
    )
    return path


def load_head_checkpoint(path: str | Path) -> MiteHead:
    """Read a ``.pt`` checkpoint into an eval-mode :class:`MiteHead`.

    Raises :class:`ModelLoadError` for a missing, foreign or mismatched file.
    """
    import torch

    from sarmission.perception.head import MiteHead

    path = Path(path)
    if not path.is_file():
        raise _fail(path, "file not found")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for foreign files
        raise _fail(path, f"not a torch checkpoint ({type(exc).__name__})") from exc
    if not isinstance(ckpt, dict) or "format" not in ckpt:
        raise _fail(path, "not a sarmission head checkpoint (no 'format' entry)")
    _check_version(path, ckpt.get("format"), ckpt.get("format_version"))
    config = _config_from(path, ckpt.get("config"))
    state = ckpt.get("state_dict")
    if not isinstance(state, dict):
        raise _fail(path, "checkpoint has no 'state_dict' dict")
    model = MiteHead(config)
    expected = model.state_dict()
    missing = sorted(set(expected) - set(state))
    unexpected = sorted(set(state) - set(expected))
    if missing or unexpected:
        raise _fail(
            path,
            f"state_dict does not match the config: missing {missing[:3]}"
            f"{'...' if len(missing) > 3 else ''}, unexpected {unexpected[:3]}"
            f"{'...' if len(unexpected) > 3 else ''}",
        )
    bad = [k for k, v in state.items() if tuple(v.shape) != tuple(expected[k].shape)]
    if bad:
        k = bad[0]
        raise _fail(
            path,
            f"state_dict shape mismatch for {k}: {tuple(state[k].shape)} "
            f"vs {tuple(expected[k].shape)} ({len(bad)} tensors differ)",
        )
    model.load_state_dict(state)
    return model.eval()


class HeadRuntime(ABC):
    """Runs the head on crops: ``predict(crops [N, 4, S, S]) -> (cls_logits [N, C], ltrb [N, 4])``.

    ``ltrb`` are DFL-decoded edge distances from the crop centre in crop pixels (see
    :func:`sarmission.perception.head.ltrb_to_boxes`). ``N = 0`` returns empty arrays without
    running the model.
    """

    def __init__(self, config: HeadConfig) -> None:
        self.config = config
        #: The model file it was loaded from (None: built in memory); files fitted for this
        #: head sit beside it (e.g. its alert confidence, :mod:`sarmission.mission.confidence`)
        self.source: Path | None = None

    @property
    def classes(self) -> tuple[str, ...]:
        """Class names, index = class id."""
        return self.config.classes

    def predict(self, crops: np.ndarray | Tensor) -> tuple[np.ndarray, np.ndarray]:
        """Class logits ``[N, C]`` and decoded ``ltrb`` ``[N, 4]`` (float32 numpy) for ``crops``."""
        c = self.config
        torch = sys.modules.get("torch")  # a tensor can only come from a process that has torch
        x = (
            crops.detach().cpu().numpy()
            if torch is not None and isinstance(crops, torch.Tensor)
            else np.asarray(crops)
        )
        expected = (c.in_channels, c.crop_size, c.crop_size)
        if x.ndim != 4 or tuple(x.shape[1:]) != expected:
            raise ValueError(
                f"crops must have shape [N, {expected[0]}, {expected[1]}, "
                f"{expected[2]}], got {list(x.shape)}"
            )
        if x.shape[0] == 0:
            return (np.zeros((0, c.num_classes), np.float32), np.zeros((0, 4), np.float32))
        logits, ltrb = self._run(np.ascontiguousarray(x, dtype=np.float32))
        return logits.astype(np.float32, copy=False), ltrb.astype(np.float32, copy=False)

    @abstractmethod
    def _run(self, crops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Run the model on a non-empty float32 batch."""


class TorchHeadRuntime(HeadRuntime):
    """Runs a :class:`MiteHead` in eval mode under ``torch.inference_mode``.

    ``num_threads`` (optional) calls ``torch.set_num_threads``, which is process-wide.
    """

    def __init__(self, model: MiteHead, num_threads: int | None = None) -> None:
        import torch

        super().__init__(model.config)
        self.model = model.eval()
        if num_threads is not None:
            torch.set_num_threads(num_threads)

    @classmethod
    def from_checkpoint(cls, path: str | Path, num_threads: int | None = None) -> TorchHeadRuntime:
        """Load a ``.pt`` checkpoint (raises :class:`ModelLoadError`)."""
        return cls(load_head_checkpoint(path), num_threads)

    def _run(self, crops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        import torch

        with torch.inference_mode():
            logits, ltrb = self.model(torch.from_numpy(crops))
        return logits.numpy(), ltrb.numpy()


def _proto_dims(value_info) -> list[int | str]:
    return [
        d.dim_param if d.dim_param else (d.dim_value if d.HasField("dim_value") else "?")
        for d in value_info.type.tensor_type.shape.dim
    ]


def _check_signature(
    path: Path | str, meta: dict[str, str], inputs: list[tuple[str, list]], outputs: list[str]
) -> HeadConfig:
    """The head config of a model with metadata ``meta``, graph inputs ``(name, dims)`` (a dim is
    an int, or a name when symbolic) and output names; :class:`ModelLoadError` when it is not a
    head this build runs."""
    if META_FORMAT not in meta:
        raise _fail(
            path,
            f"ONNX model has no '{META_FORMAT}' metadata (export it with "
            "sarmission.perception.export.export_head_onnx)",
        )
    try:
        version = int(meta.get(META_VERSION, ""))
        raw_config = json.loads(meta.get(META_CONFIG, ""))
    except ValueError as exc:
        raise _fail(path, f"unreadable sarmission metadata ({exc})") from exc
    _check_version(path, meta[META_FORMAT], version)
    config = _config_from(path, raw_config)
    if len(inputs) != 1 or inputs[0][0] != INPUT_NAME:
        raise _fail(path, f"expected one input '{INPUT_NAME}', got {[i[0] for i in inputs]}")
    dims = inputs[0][1]
    want = [config.in_channels, config.crop_size, config.crop_size]
    if len(dims) != 4 or dims[1:] != want:
        raise _fail(
            path,
            f"input '{INPUT_NAME}' has shape {dims}, expected [N, {want[0]}, {want[1]}, {want[2]}]",
        )
    if not isinstance(dims[0], str):
        raise _fail(
            path, f"input '{INPUT_NAME}' has a fixed proposal axis {dims[0]}; it must be dynamic"
        )
    if tuple(outputs) != OUTPUT_NAMES:
        raise _fail(path, f"expected outputs {list(OUTPUT_NAMES)}, got {outputs}")
    return config


def _session_config(path: Path | str, session) -> HeadConfig:
    """:func:`_check_signature` on what an onnxruntime session reads of the model."""
    inputs = [(i.name, ["?" if d is None else d for d in i.shape]) for i in session.get_inputs()]
    return _check_signature(
        path,
        dict(session.get_modelmeta().custom_metadata_map),
        inputs,
        [o.name for o in session.get_outputs()],
    )


def _rejection(path: Path | str, data: bytes, exc: Exception) -> ModelLoadError:
    """Why onnxruntime refused ``data``, in the user's terms: not ONNX at all, not a head of
    ours (read with the ``onnx`` package, on this error path only), or onnxruntime's reason."""
    import onnx

    try:
        model = onnx.load_from_string(data)
    except Exception as decode_exc:  # protobuf decode errors have several types
        return _fail(path, f"not an ONNX model ({type(decode_exc).__name__})")
    initialisers = {init.name for init in model.graph.initializer}
    inputs = [(i.name, _proto_dims(i)) for i in model.graph.input if i.name not in initialisers]
    try:
        _check_signature(
            path,
            {p.key: p.value for p in model.metadata_props},
            inputs,
            [o.name for o in model.graph.output],
        )
    except ModelLoadError as wrong:
        return wrong
    return _fail(path, f"onnxruntime rejected the model ({str(exc).splitlines()[0]})")


class OnnxHeadRuntime(HeadRuntime):
    """Runs an exported head with onnxruntime's ``CPUExecutionProvider``.

    ``source`` is a ``.onnx`` path or the serialised model bytes (``name`` is then used in errors).
    ``intra_op_threads`` defaults to the process's thread plan (:mod:`sarmission.threads`).
    """

    def __init__(
        self,
        source: str | Path | bytes,
        intra_op_threads: int | None = None,
        name: str | None = None,
    ) -> None:
        import onnxruntime as ort

        from sarmission.threads import thread_plan

        label = name or ("<bytes>" if isinstance(source, bytes) else str(source))
        if isinstance(source, bytes):
            data = source
        else:
            if not Path(source).is_file():
                raise _fail(label, "file not found")
            data = Path(source).read_bytes()
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = intra_op_threads or thread_plan().onnx
        opts.inter_op_num_threads = 1
        # No busy-waiting after a run: the vSTMD and crop stages need those cores next.
        opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
        opts.log_severity_level = 3  # a foreign file is reported below, in one line
        try:
            self.session = ort.InferenceSession(data, opts, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception classes
            raise _rejection(label, data, exc) from exc
        super().__init__(_session_config(label, self.session))

    def _run(self, crops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        logits, ltrb = self.session.run(list(OUTPUT_NAMES), {INPUT_NAME: crops})
        return logits, ltrb


RuntimeName = Literal["auto", "torch", "onnx"]


def load_head_runtime(
    path: str | Path, runtime: RuntimeName = "auto", intra_op_threads: int | None = None
) -> HeadRuntime:
    """Load a head model file, or a shipped head by name (:mod:`sarmission.models`:
    ``maritime``, ``land``, ``default``), into a runtime.

    ``auto`` picks by extension: ``.pt``/``.pth`` → :class:`TorchHeadRuntime`, ``.onnx`` →
    :class:`OnnxHeadRuntime` (a name: the shipped ONNX). ``onnx`` with a checkpoint exports it
    in memory first; ``torch`` with an ONNX file is an error. ``intra_op_threads`` applies to
    onnxruntime only (default: the thread plan's).
    """
    from sarmission.models import SHIPPED_HEADS, is_head_name, shipped_head_path

    if is_head_name(path):
        try:
            path = shipped_head_path(str(path), "torch" if runtime == "torch" else "onnx")
        except SarmissionError as exc:
            raise ModelLoadError(str(exc)) from exc
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in TORCH_SUFFIXES + ONNX_SUFFIXES:
        raise _fail(
            path,
            f"unknown model extension '{suffix}' (use .pt, .pth or .onnx, or a shipped "
            f"head's name: {', '.join(SHIPPED_HEADS)})",
        )
    if runtime not in ("auto", "torch", "onnx"):
        raise ValueError(f"runtime must be 'auto', 'torch' or 'onnx', got {runtime!r}")
    is_onnx = suffix in ONNX_SUFFIXES
    if runtime == "torch" and is_onnx:
        raise _fail(path, "the torch runtime needs a .pt checkpoint, not an ONNX file")
    loaded: HeadRuntime
    if is_onnx:
        loaded = OnnxHeadRuntime(path, intra_op_threads)
    else:
        model = load_head_checkpoint(path)
        if runtime == "onnx":
            from sarmission.perception.export import head_onnx_bytes

            loaded = OnnxHeadRuntime(head_onnx_bytes(model), intra_op_threads, name=str(path))
        else:
            loaded = TorchHeadRuntime(model)
    loaded.source = path
    return loaded
