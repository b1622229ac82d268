"""MITE-Net lightweight R-CNN-like head (paper section 3.2).

Input: motion-enhanced crops ``[N, 4, S, S]`` (S = 16: RGB in [0, 1] and the enhanced response E,
see :mod:`sarmission.perception.crops`). Layers::

    CoordConv      append x, y in [-1, 1]                                   → 6 x S x S
    stem           conv3x3 6→w0, BN, ReLU                                   → w0 x S x S
    block d=2      conv3x3(d2) w0→w1, BN, ReLU, conv3x3(d2) w1→w1, BN, + 1x1 skip, ReLU
    block d=4      conv3x3(d4) w1→w1, BN, ReLU, conv3x3(d4) w1→w1, BN, + identity, ReLU
    classification depthwise conv3x3, BN, ReLU; channel attention from global max- and
                   average-pooled features through a shared MLP (sigmoid gate);
                   [max, avg] pooled → MLP → C logits
    regression     bottleneck conv1x1 w1→b, BN, ReLU; flatten (b x S x S) → linear → 4 x (R+1)
                   Distribution Focal Loss bins (R = reg_max = 16); the flattened map keeps where
                   in the crop each edge lies

No pooling in the backbone: every feature map stays S x S; the receptive field grows through the
dilations (stem 3 px, then +4 +4 for the d=2 layers and +8 +8 for the d=4 layers: 27 px, more
than the whole crop). The box is decoded from the DFL bins as the
softmax expectation ``d = sum_i softmax(z)_i * i`` per edge: left, top, right, bottom distances from
the crop centre, in crop pixels (one crop pixel = box side / S in full-resolution pixels).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from sarmission.perception.head_config import DEFAULT_CLASSES, HeadConfig, ltrb_to_boxes


def _conv_bn(
    c_in: int, c_out: int, k: int = 3, dilation: int = 1, groups: int = 1
) -> nn.Sequential:
    pad = dilation * (k // 2)
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, k, padding=pad, dilation=dilation, groups=groups, bias=False),
        nn.BatchNorm2d(c_out),
    )


class DilatedResBlock(nn.Module):
    """Two dilated 3x3 conv-BN layers and a residual link (1x1 projection if widths differ)."""

    def __init__(self, c_in: int, c_out: int, dilation: int) -> None:
        super().__init__()
        self.conv1 = _conv_bn(c_in, c_out, dilation=dilation)
        self.conv2 = _conv_bn(c_out, c_out, dilation=dilation)
        self.skip = nn.Identity() if c_in == c_out else _conv_bn(c_in, c_out, k=1)
        self.act = nn.ReLU(inplace=True)

    def forward(self, x: Tensor) -> Tensor:
        """``[N, c_in, H, W]`` → ``[N, c_out, H, W]``."""
        y = self.conv2(self.act(self.conv1(x)))
        return self.act(y + self.skip(x))


class ClassificationBranch(nn.Module):
    """Depthwise spatial mixing, then max- and average-pool channel attention, then class logits."""

    def __init__(self, channels: int, num_classes: int, reduction: int, hidden: int) -> None:
        super().__init__()
        self.dw = nn.Sequential(
            _conv_bn(channels, channels, groups=channels), nn.ReLU(inplace=True)
        )
        mid = max(channels // reduction, 1)
        self.attn = nn.Sequential(
            nn.Linear(channels, mid), nn.ReLU(inplace=True), nn.Linear(mid, channels)
        )
        self.fc = nn.Sequential(
            nn.Linear(2 * channels, hidden), nn.ReLU(inplace=True), nn.Linear(hidden, num_classes)
        )

    def forward(self, x: Tensor) -> Tensor:
        """``[N, C, H, W]`` → logits ``[N, num_classes]``."""
        f = self.dw(x)
        gate = torch.sigmoid(self.attn(f.amax(dim=(2, 3))) + self.attn(f.mean(dim=(2, 3))))
        f = f * gate[:, :, None, None]
        return self.fc(torch.cat([f.amax(dim=(2, 3)), f.mean(dim=(2, 3))], dim=1))


class RegressionBranch(nn.Module):
    """Conv bottleneck → flatten → linear to ``4 x (reg_max + 1)`` DFL bin logits."""

    def __init__(self, channels: int, bottleneck: int, crop_size: int, reg_max: int) -> None:
        super().__init__()
        self.reg_max = reg_max
        self.conv = nn.Sequential(_conv_bn(channels, bottleneck, k=1), nn.ReLU(inplace=True))
        self.fc = nn.Linear(bottleneck * crop_size * crop_size, 4 * (reg_max + 1))

    def forward(self, x: Tensor) -> Tensor:
        """``[N, C, H, W]`` → bin logits ``[N, 4, reg_max + 1]`` (order l, t, r, b)."""
        return self.fc(self.conv(x).flatten(1)).reshape(-1, 4, self.reg_max + 1)


def dfl_decode(bin_logits: Tensor) -> Tensor:
    """Softmax expectation over DFL bins: ``[..., R + 1]`` logits → ``[...]`` distances in bins."""
    bins = torch.arange(bin_logits.shape[-1], dtype=bin_logits.dtype, device=bin_logits.device)
    return (torch.softmax(bin_logits, dim=-1) * bins).sum(dim=-1)


def normalise_crop_colour(crops: Tensor, floor: float) -> Tensor:
    """``crops [N, 4, S, S]`` with RGB relative to each crop: its mean colour taken away, then
    divided by its RGB spread, at least ``floor``; the motion channel as it is."""
    rgb, motion = crops[:, :3], crops[:, 3:]
    centred = rgb - rgb.mean(dim=(2, 3), keepdim=True)
    spread = centred.pow(2).mean(dim=(1, 2, 3), keepdim=True).sqrt()
    return torch.cat([centred / spread.clamp(min=floor), motion], dim=1)


def coord_channels(size: int) -> Tensor:
    """CoordConv channels ``[1, 2, size, size]``: x then y, pixel centres spanning [-1, 1]."""
    t = torch.linspace(-1.0, 1.0, size)
    yy, xx = torch.meshgrid(t, t, indexing="ij")
    return torch.stack([xx, yy])[None]


class MiteHead(nn.Module):
    """The MITE-Net head. ``forward(crops) -> (cls_logits [N, C], ltrb [N, 4])``.

    ``ltrb`` are the decoded left/top/right/bottom distances from the crop centre in crop pixels
    (0..reg_max). Use :meth:`forward_with_bins` in training to get the DFL bin logits as well.
    """

    def __init__(self, config: HeadConfig | None = None) -> None:
        super().__init__()
        self.config = config or HeadConfig()
        self.config.validate()
        c = self.config
        w0, w1 = c.widths
        self.register_buffer("coords", coord_channels(c.crop_size), persistent=False)
        self.stem = nn.Sequential(_conv_bn(c.in_channels + 2, w0), nn.ReLU(inplace=True))
        self.backbone = nn.Sequential(DilatedResBlock(w0, w1, 2), DilatedResBlock(w1, w1, 4))
        self.cls_branch = ClassificationBranch(
            w1, c.num_classes, c.attention_reduction, c.cls_hidden
        )
        self.reg_branch = RegressionBranch(w1, c.reg_bottleneck, c.crop_size, c.reg_max)

    def forward_with_bins(self, crops: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """``crops [N, 4, S, S]`` → ``(cls_logits [N, C], bin_logits [N, 4, R+1], ltrb [N, 4])``."""
        if self.config.crop_norm > 0:
            crops = normalise_crop_colour(crops, self.config.crop_norm)
        coords = self.coords.expand(crops.shape[0], -1, -1, -1)
        f = self.backbone(self.stem(torch.cat([crops, coords], dim=1)))
        bins = self.reg_branch(f)
        return self.cls_branch(f), bins, dfl_decode(bins)

    def forward(self, crops: Tensor) -> tuple[Tensor, Tensor]:
        """``crops [N, 4, S, S]`` → ``(cls_logits [N, C], ltrb [N, 4])`` in crop pixels."""
        logits, _, ltrb = self.forward_with_bins(crops)
        return logits, ltrb


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


def head_flops_per_proposal(model: MiteHead) -> int:
    """FLOPs of one proposal through the head: 2 x multiply-accumulates of every conv and linear.

    Counted by running one zero crop through the module with forward hooks on ``nn.Conv2d`` and
    ``nn.Linear`` (normalisation, activations, attention gating and the DFL softmax are not counted,
    as in the usual MAC-based convention).
    """
    macs = 0

    def hook(module: nn.Module, inputs: tuple[Tensor, ...], output: Tensor) -> None:
        nonlocal macs
        if isinstance(module, nn.Conv2d):
            k = module.kernel_size[0] * module.kernel_size[1] * module.in_channels // module.groups
            macs += output.numel() * k
        else:
            macs += output.numel() * module.in_features

    handles = [
        m.register_forward_hook(hook)
        for m in model.modules()
        if isinstance(m, nn.Conv2d | nn.Linear)
    ]
    c = model.config
    was_training = model.training
    try:
        model.eval()
        with torch.no_grad():
            model(torch.zeros(1, c.in_channels, c.crop_size, c.crop_size))
    finally:
        for h in handles:
            h.remove()
        model.train(was_training)
    return 2 * macs


__all__ = [
    "DEFAULT_CLASSES",
    "HeadConfig",
    "MiteHead",
    "count_parameters",
    "dfl_decode",
    "head_flops_per_proposal",
    "ltrb_to_boxes",
    "normalise_crop_colour",
]
