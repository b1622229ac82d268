"""Export the MITE-Net head to ONNX (dynamic proposal axis) and verify it against torch."""

from __future__ import annotations

import copy
import io
import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import onnx
import torch

from sarmission.perception.head import MiteHead, count_parameters
from sarmission.perception.runtime import (
    FORMAT_VERSION,
    INPUT_NAME,
    META_CONFIG,
    META_FORMAT,
    META_VERSION,
    MODEL_FORMAT,
    OUTPUT_NAMES,
    OnnxHeadRuntime,
    TorchHeadRuntime,
    load_head_checkpoint,
)


@dataclass(frozen=True)
class ExportReport:
    """Result of :func:`export_head_onnx`."""

    path: Path
    opset: int
    num_parameters: int
    max_abs_diff: float

    def summary(self) -> str:
        """One line for the console: what was written and how closely ONNX matches torch."""
        return (
            f"wrote {self.path}: {self.num_parameters:,} parameters, opset {self.opset}, "
            f"max |onnx - torch| {self.max_abs_diff:.2e}"
        )


def head_onnx_bytes(model: MiteHead, opset: int = 17) -> bytes:
    """Serialised ONNX of ``model`` (eval mode, TorchScript exporter) with sarmission metadata.

    Input ``crops`` ``[N, 4, S, S]`` and outputs ``cls_logits`` ``[N, C]``, ``ltrb`` ``[N, 4]``
    all share the symbolic axis ``N``.
    """
    m = copy.deepcopy(model).cpu().eval()
    c = m.config
    example = torch.zeros(2, c.in_channels, c.crop_size, c.crop_size)
    buf = io.BytesIO()
    dynamic = {name: {0: "N"} for name in (INPUT_NAME, *OUTPUT_NAMES)}
    with warnings.catch_warnings():  # the TorchScript exporter is deprecated but chosen on purpose
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.onnx.export(
            m,
            (example,),
            buf,
            dynamo=False,
            opset_version=opset,
            input_names=[INPUT_NAME],
            output_names=list(OUTPUT_NAMES),
            dynamic_axes=dynamic,
            do_constant_folding=True,
        )
    proto = onnx.load_from_string(buf.getvalue())
    for key, value in (
        (META_FORMAT, MODEL_FORMAT),
        (META_VERSION, str(FORMAT_VERSION)),
        (META_CONFIG, json.dumps(c.to_dict())),
    ):
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value
    proto.producer_name = "sarmission"
    return proto.SerializeToString()


def export_head_onnx(
    checkpoint_or_module: str | Path | MiteHead,
    out_path: str | Path,
    opset: int = 17,
    num_check: int = 16,
    seed: int = 0,
    atol: float = 1e-4,
) -> ExportReport:
    """Write the head as ONNX, check it with ``onnx.checker`` and compare onnxruntime with torch.

    The comparison runs ``num_check`` random crops (seeded) through both runtimes; the largest
    absolute difference over logits and ``ltrb`` is reported, and above ``atol`` the export is
    rejected with ``RuntimeError`` (the file is left for inspection).
    """
    if isinstance(checkpoint_or_module, MiteHead):
        model = checkpoint_or_module
    else:
        model = load_head_checkpoint(checkpoint_or_module)
    bad = [name for name, value in model.state_dict().items() if not value.isfinite().all()]
    if bad:  # a diverged training writes such a head: it would detect nothing, silently
        raise ValueError(f"the head's weights are not finite ({bad[0]} ...): not exported")
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    data = head_onnx_bytes(model, opset)
    onnx.checker.check_model(onnx.load_from_string(data), full_check=True)
    out_path.write_bytes(data)

    c = model.config
    crops = np.random.default_rng(seed).random(
        (num_check, c.in_channels, c.crop_size, c.crop_size), dtype=np.float32
    )
    ref = TorchHeadRuntime(copy.deepcopy(model)).predict(crops)
    got = OnnxHeadRuntime(out_path).predict(crops)
    diff = float(max(np.abs(a - b).max() for a, b in zip(ref, got, strict=True)))
    if not diff <= atol:  # NaN too
        out_path.unlink(missing_ok=True)
        raise RuntimeError(f"ONNX export {out_path} differs from torch by {diff:.3g} > {atol:g}")
    return ExportReport(out_path, opset, count_parameters(model), diff)
