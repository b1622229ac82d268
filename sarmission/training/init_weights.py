"""Start a training run from a trained head's weights (``sarmission train --init``).

Fine-tuning a shipped head on a user's own dataset needs far fewer examples than training from
scratch. The new head must have the trained one's architecture (widths, crop size, regression
bins); its classes may differ: the class layer's rows of classes both heads name are carried
over, rows of new classes start fresh, so a maritime head can learn ``person`` beside its
swimmers, unless ``renamed`` says which trained class a new one starts from (``person`` from
``swimmer``: a land head that begins where the maritime head already finds people on land).
Every other weight is copied.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import torch

from sarmission.class_roles import normalise_class
from sarmission.perception.head import HeadConfig, MiteHead
from sarmission.perception.runtime import load_head_checkpoint


@dataclass(frozen=True)
class InitReport:
    """What was carried over from the trained head."""

    source: Path
    carried_classes: tuple[str, ...]
    new_classes: tuple[str, ...]

    def summary(self) -> str:
        """One line, e.g. ``initialised from X: classes swimmer carried, person new``."""
        parts = [f"classes {', '.join(self.carried_classes) or 'none'} carried"]
        if self.new_classes:
            parts.append(f"{', '.join(self.new_classes)} new")
        return f"initialised from {self.source}: {'; '.join(parts)}"


def init_path(value: str | Path, flag: str = "--init") -> Path:
    """The checkpoint ``flag`` names (``default``: the shipped default head's ``.pt``;
    ``maritime``, ``land``: that shipped head's)."""
    from sarmission.models import is_head_name, shipped_head_path

    if is_head_name(value):
        return shipped_head_path(str(value), "torch")
    path = Path(value)
    if path.suffix.lower() not in (".pt", ".pth"):
        raise ValueError(f"{flag} needs a .pt checkpoint (the trained head), got {path}")
    return path


def architecture_differences(mine: HeadConfig, theirs: HeadConfig) -> list[str]:
    """``"name theirs vs mine"`` for every setting but the classes in which two heads differ
    (empty when one's weights fit the other)."""
    a = {k: v for k, v in asdict(mine).items() if k != "classes"}
    b = {k: v for k, v in asdict(theirs).items() if k != "classes"}
    return [f"{k} {b.get(k)} vs {a[k]}" for k in sorted(a) if a[k] != b.get(k)]


def initialise_from(
    model: MiteHead, source: str | Path, renamed: dict[str, str] | None = None
) -> InitReport:
    """Copy the weights of the checkpoint ``source`` into ``model`` (module docstring);
    ``renamed``: new class -> the trained class its row starts from.

    Raises :class:`~sarmission.perception.runtime.ModelLoadError` for an unreadable file and
    ``ValueError`` when the architectures differ."""
    path = init_path(source)
    trained = load_head_checkpoint(path)
    differ = architecture_differences(model.config, trained.config)
    if differ:
        raise ValueError(
            f"--init {path}: its architecture differs from the head being trained "
            f"({', '.join(differ)})"
        )
    layer = model.cls_branch.fc[-1]
    old_layer = trained.cls_branch.fc[-1]
    skip = {name for name, p in model.named_parameters() if p is layer.weight or p is layer.bias}
    state = {k: v for k, v in trained.state_dict().items() if k not in skip}
    model.load_state_dict(state, strict=False)
    old_index = {normalise_class(c): i for i, c in enumerate(trained.config.classes)}
    renamed = {normalise_class(k): normalise_class(v) for k, v in (renamed or {}).items()}
    unknown = sorted(set(renamed.values()) - set(old_index))
    if unknown:
        raise ValueError(
            f"--init-class: {path} has no class {', '.join(unknown)} "
            f"(it has {', '.join(trained.config.classes)})"
        )
    own = {normalise_class(c) for c in model.config.classes}
    stray = sorted(set(renamed) - own)
    if stray:  # a typo would leave the class it meant to start from scratch, silently
        raise ValueError(
            f"--init-class: the head being trained has no class {', '.join(stray)} "
            f"(it has {', '.join(model.config.classes)})"
        )
    carried, new = [], []
    with torch.no_grad():
        for row, name in enumerate(model.config.classes):
            key = normalise_class(name)
            old = old_index.get(renamed.get(key, key))
            if old is None:
                new.append(name)
                continue
            layer.weight[row] = old_layer.weight[old]
            layer.bias[row] = old_layer.bias[old]
            carried.append(name if key not in renamed else f"{name} (from {renamed[key]})")
    return InitReport(path, tuple(carried), tuple(new))
