"""Bone-length spread of the raw network positions (Kaufmann et al. 2020, §4.1, Fig. 5).

The networks predict positions, not angles, so nothing ties their bones to fixed
lengths until IK. This measures, for every bone of non-zero rest length, the length in
each frame of the raw output (diagnostic ``raw_positions``) minus the true length (the
clip's own skeleton), in cm, over the clips of a split, for pure reconstruction (the
paper's setting) or another corruption.

    python -m engines.cae.bone_lengths --engines cae,holden --split test --corrupt none

prints a markdown table: per bone its true length (mean over the clips) and per engine
the median error, the interquartile range and the 5-95 % range (cm).
"""

from __future__ import annotations

import argparse
from typing import Sequence

import numpy as np

from workbench import registry
from workbench.corruption import parse_corruption
from workbench.data import catalogue, select
from workbench.metrics import bone_lengths


def length_errors_cm(
    engine_specs: Sequence[str], motions, corruption: str = "none", seed: int = 0
) -> tuple[list[str], np.ndarray, dict[str, np.ndarray]]:
    """Bone names (B,), true lengths (B,) averaged over the motions, and per engine the
    raw-output length minus the true length, (frames of all motions, B), in cm."""
    skeleton = motions[0].skeleton
    bones = [(p, j) for p, j in skeleton.bones if np.linalg.norm(skeleton.offsets[j]) > 1e-9]
    child = np.array([j for _, j in bones])
    names = [f"{skeleton.names[p]}-{skeleton.names[j]}" for p, j in bones]
    truth = np.mean([np.linalg.norm(m.skeleton.offsets[child], axis=1) * m.skeleton.unit_cm for m in motions], axis=0)
    engines = {spec: registry.create(spec) for spec in engine_specs}
    errors: dict[str, list[np.ndarray]] = {spec: [] for spec in engine_specs}
    for motion in motions:
        obs = parse_corruption(corruption).apply(motion, seed)
        true = np.linalg.norm(motion.skeleton.offsets[child], axis=1) * motion.skeleton.unit_cm
        for spec, engine in engines.items():
            raw = engine.clean(obs).diagnostics["raw_positions"]
            lengths = bone_lengths(raw, motion.skeleton.parents)[:, child - 1] * motion.skeleton.unit_cm
            errors[spec].append(lengths - true)
    return names, truth, {spec: np.concatenate(e) for spec, e in errors.items()}


def markdown(names: list[str], truth: np.ndarray, errors: dict[str, np.ndarray]) -> str:
    """One row per bone: true length, then per engine median [IQR] (5-95 % range) in cm."""
    head = "| bone | true cm | " + " | ".join(f"{s}: median [IQR] (5-95 %)" for s in errors) + " |"
    lines = [head, "|" + "---|" * (2 + len(errors))]
    rows = list(range(len(names))) + [None]
    for b in rows:
        cells = []
        for e in errors.values():
            x = np.abs(e).ravel() if b is None else e[:, b]
            q5, q25, q50, q75, q95 = np.percentile(x, [5, 25, 50, 75, 95])
            cells.append(f"{q50:{'' if b is None else '+'}.2f} [{q75 - q25:.2f}] ({q95 - q5:.2f})")
        label, true = ("all bones, abs error", "") if b is None else (names[b], f"{truth[b]:.1f}")
        lines.append(f"| {label} | {true} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engines", default="cae,holden,cae-vanilla")
    ap.add_argument("--split", default="test", choices=["train", "test"])
    ap.add_argument("--corrupt", default="none")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    motions = [c.load() for c in select(catalogue(), args.split, dataset="cmu")]
    print(markdown(*length_errors_cm(args.engines.split(","), motions, args.corrupt, args.seed)))


if __name__ == "__main__":
    main()
