"""``printapp bench frames``: orthonormal bases from unit normals, speed and orthonormality.

Normals per second for Duff's and Frisvad's bases, and their orthonormality error
against 1 + n.z, where Frisvad's fails.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from printapp.bench.timing import StageResult, median_seconds


def bench_frames(repeats: int) -> StageResult:
    """Duff's and Frisvad's orthonormal bases: normals per second and orthonormality error."""
    from noise.frames import onb

    rng = np.random.default_rng(0)
    n = 1_000_000
    uniform = rng.normal(size=(n // 2, 3))
    uniform /= np.linalg.norm(uniform, axis=1, keepdims=True)
    eps = 10 ** rng.uniform(-12, 0, n - n // 2)
    r = np.sqrt(eps * (2 - eps))
    phi = rng.uniform(0, 2 * np.pi, eps.size)
    clustered = np.column_stack([r * np.cos(phi), r * np.sin(phi), -1 + eps])
    normals64 = np.concatenate([uniform, clustered])
    one_plus_z = 1 + normals64[:, 2]
    rows = []
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    edges = np.logspace(-12, 0, 25)
    for dtype in (np.float32, np.float64):
        normals = normals64.astype(dtype)
        for method in ("duff", "frisvad"):
            seconds, _ = median_seconds(lambda m=method, x=normals: onb(x, m), repeats)
            b1, b2 = onb(normals, method)
            basis = np.stack([b1, b2, normals], axis=1).astype(np.float64)
            error = np.abs(np.einsum("kij,klj->kil", basis, basis) - np.eye(3)).max(axis=(1, 2))
            rows.append(
                {
                    "method": method,
                    "dtype": np.dtype(dtype).name,
                    "M_normals_s": round(n / seconds / 1e6, 1),
                    "max_error": float(f"{error.max():.3g}"),
                    "max_error_far_from_pole": float(f"{error[one_plus_z > 0.5].max():.3g}"),
                }
            )
            which = np.digitize(one_plus_z, edges)
            worst = np.array(
                [error[which == b].max() if np.any(which == b) else np.nan for b in range(1, len(edges))]
            )
            curves[f"{method} {np.dtype(dtype).name}"] = (np.sqrt(edges[1:] * edges[:-1]), worst)

    def chart(path: Path) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.5, 4), dpi=110)
        for label, (x, y) in curves.items():
            ax.loglog(x, np.maximum(y, 1e-18), "-" if "duff" in label else "--", label=label)
        ax.set_xlabel("1 + n.z (distance from the south pole)")
        ax.set_ylabel("max |B B^T - I|")
        ax.set_title("orthonormal bases near n = (0, 0, -1)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path)
        plt.close(fig)

    return StageResult(
        "frames", "orthonormal bases from 1e6 unit normals (half near the south pole)", rows, chart
    )
