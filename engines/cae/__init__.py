"""Convolutional autoencoders over the motion image (Kaufmann et al. 2020, "Convolutional
Autoencoders for Human Motion Infilling", 3DV) and their Table 1 baselines:

* ``cae``: the paper's model (VGG-style 2-D convolutional autoencoder, gap curriculum);
* ``cae-vanilla``: the "Vanilla AE" ablation, one strided convolution per unit;
* ``holden``: Holden et al. (2016)'s motion manifold, a temporal convolution over frames
  with max pooling and unpooling.

All three share the representation (:mod:`.representation`), the training loop
(:mod:`.training`) and inference with IK back to joint angles (:mod:`.engine`); only the
network differs (:mod:`.networks`). Committed weights live in ``weights/<name>/<dataset>/``.
"""

from __future__ import annotations

from dataclasses import dataclass

from workbench.engine import EngineInfo, trained, training

from .engine import ConvAutoencoderEngine, TrainingParams

CITATION = "Kaufmann, Aksan, Song, Pece, Ziegler, Hilliges 2020, Convolutional Autoencoders for Human Motion Infilling"
TASKS = frozenset({"fill", "denoise"})


@dataclass(frozen=True)
class ImageParams(TrainingParams):
    """Encoder widths: ``base_width`` channels in the first unit, doubling per unit up
    to ``top_width``."""

    base_width: int = trained(16)
    top_width: int = trained(192)

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 1 <= self.base_width <= self.top_width:
            raise ValueError(f"want 1 <= base_width <= top_width, got {self.base_width} and {self.top_width}")


@dataclass(frozen=True)
class CAEParams(ImageParams):
    """``cae``'s defaults: stronger augmentation than the baselines' (continuous speeds
    within 50 %, bodies scaled within 5 %, four copies of every clip with upper-body
    angles offset by N(0, 15^2) degrees, input noise 0.1), as our six training subjects
    are few: on two held-out training subjects (05, 06; trained on the other four) the
    reconstruction error fell from 8.6 to 7.6 cm with the first three, to 6.0 cm with
    two pose copies at 10 degrees and to 5.6 cm with four at 15; the 60-frame gap error
    from 9.2 to 8.7, 7.2 and 6.8 cm."""

    time_scale_pct: float = training(50.0)
    body_scale_pct: float = training(5.0)
    input_noise: float = training(0.1)
    pose_copies: int = training(4)
    pose_jitter_deg: float = training(15.0)


@dataclass(frozen=True)
class HoldenParams(TrainingParams):
    """``hidden`` feature channels of the temporal convolution, ``kernel_frames`` wide (odd)."""

    hidden: int = trained(256)
    kernel_frames: int = trained(25)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.hidden < 1 or self.kernel_frames < 1 or self.kernel_frames % 2 == 0:
            raise ValueError(
                f"hidden must be at least 1 and kernel_frames odd and positive, got {self.hidden} and "
                f"{self.kernel_frames}"
            )


class CAE(ConvAutoencoderEngine):
    """Kaufmann et al.'s convolutional autoencoder with the gap curriculum."""

    info = EngineInfo(
        name="cae",
        summary="convolutional autoencoder over the pose x time image (Kaufmann 2020); IK back to angles",
        tasks=TASKS,
        space="positions",
        trainable=True,
        citation=CITATION + ", §3",
    )
    Params = CAEParams

    def build_network(self, n_rows: int):
        from .networks import KaufmannNet

        return KaufmannNet(self.params.base_width, self.params.top_width, self.params.bf16)


class VanillaCAE(ConvAutoencoderEngine):
    """The "Vanilla AE" ablation of Table 1: one strided convolution per unit."""

    info = EngineInfo(
        name="cae-vanilla",
        summary="Kaufmann 2020's Vanilla AE ablation: one strided 3x3 convolution per unit",
        tasks=TASKS,
        space="positions",
        trainable=True,
        citation=CITATION + ", §4.1 (Vanilla AE)",
    )
    Params = ImageParams

    def build_network(self, n_rows: int):
        from .networks import VanillaNet

        return VanillaNet(self.params.base_width, self.params.top_width, self.params.bf16)


class Holden(ConvAutoencoderEngine):
    """Holden et al.'s motion manifold (temporal convolution, max pooling / unpooling)."""

    info = EngineInfo(
        name="holden",
        summary="Holden 2016's motion manifold: 1-D convolution over frames, pooling/unpooling",
        tasks=TASKS,
        space="positions",
        trainable=True,
        citation="Holden, Saito, Komura 2016, A Deep Learning Framework for Character Motion Synthesis and "
        "Editing, §4 (as the baseline of " + CITATION + ", Table 1)",
    )
    Params = HoldenParams

    def build_network(self, n_rows: int):
        from .networks import HoldenNet

        return HoldenNet(n_rows, self.params.hidden, self.params.kernel_frames, self.params.bf16)


__all__ = ["CAE", "VanillaCAE", "Holden", "ConvAutoencoderEngine"]
