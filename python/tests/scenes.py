"""Box sets for the tests and the benchmark, made with NumPy from a seed (printed by the test
that fails, through its parameters), after the C tests' corpus (scenes/scenes.h)."""

from __future__ import annotations

import numpy as np

F32_MAX = float(np.finfo(np.float32).max)


def _boxes(lo: np.ndarray, size: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.concatenate([lo, lo + size], axis=1), dtype=np.float32)


def uniform_density(n: int, seed: int = 1, overlaps_per_box: float = 1.0) -> np.ndarray:
    """Sides 0.5..1.5 in a cube grown with cbrt(n): about overlaps_per_box overlaps per box
    whatever n is (the C benchmark's uniform scene)."""
    rng = np.random.default_rng(seed)
    side = 2.0 * np.cbrt(max(n - 1, 1) / overlaps_per_box)
    size = rng.uniform(0.5, 1.5, (n, 3))
    lo = rng.uniform(-side / 2, side / 2, (n, 3)) - size / 2
    return _boxes(lo, size)


def heavy_tailed(n: int, seed: int = 1) -> np.ndarray:
    """Uniform density with heavy-tailed sizes: ~1% of sides 4..8, ~0.01% (and box n/2) 16..32."""
    rng = np.random.default_rng(seed)
    side = 2.0 * np.cbrt(max(n - 1, 1))
    u = rng.uniform(0, 1, n)
    size = rng.uniform(0.5, 1.5, (n, 3))
    medium = u < 0.01
    size[medium] = rng.uniform(4, 8, (int(medium.sum()), 3))
    huge = u < 0.0001
    if n:
        huge[n // 2] = True
    size[huge] = rng.uniform(16, 32, (int(huge.sum()), 3))
    lo = rng.uniform(-side / 2, side / 2, (n, 3)) - size / 2
    return _boxes(lo, size)


def touching(n: int, seed: int = 1) -> np.ndarray:
    """Unit boxes on an integer lattice, shuffled: faces, edges and corners touch exactly."""
    rng = np.random.default_rng(seed)
    k = int(np.ceil(np.cbrt(n))) + 1
    cells = rng.permutation(k**3)[:n]
    lo = np.stack([cells % k, (cells // k) % k, cells // (k * k)], axis=1).astype(np.float64)
    return _boxes(lo, np.ones((n, 3)))


def same_x(n: int, seed: int = 1) -> np.ndarray:
    """Every box with the same x interval: a sweep along x meets all of them."""
    rng = np.random.default_rng(seed)
    b = uniform_density(n, seed)
    b[:, 0], b[:, 3] = 0.0, 1.0
    # a few share a min x or max x with the others' max / min: touching on x
    k = rng.choice(n, size=max(n // 10, 1), replace=False) if n else []
    b[k, 0], b[k, 3] = 1.0, 2.0
    return b


def nested(n: int, seed: int = 1) -> np.ndarray:
    """Boxes inside boxes: shells around a few centres, each containing the smaller ones."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-50, 50, (max(n // 50, 1), 3))
    c = centres[rng.integers(0, len(centres), n)]
    half = rng.uniform(0.01, 20.0, (n, 1)) * np.ones((1, 3))
    return _boxes(c - half, 2 * half)


def identical(n: int, seed: int = 1) -> np.ndarray:
    """~64 exact copies of each of a few boxes, shuffled."""
    base = uniform_density(1 + n // 64, seed, 4.0)
    rng = np.random.default_rng(seed)
    return np.ascontiguousarray(base[rng.integers(0, len(base), n)])


def points_planes(n: int, seed: int = 1) -> np.ndarray:
    """Zero extent on some or all axes (points, segments, planes) on a coarse lattice, so equal
    coordinates are common."""
    rng = np.random.default_rng(seed)
    lo = rng.integers(0, 6, (n, 3)).astype(np.float64)
    size = rng.integers(0, 2, (n, 3)).astype(np.float64)
    return _boxes(lo, size)


def signed_zero(n: int, seed: int = 1) -> np.ndarray:
    """Bounds of -0.0 and +0.0: boxes that meet only at zero, where -0.0 equals 0.0."""
    rng = np.random.default_rng(seed)
    b = np.empty((n, 6), np.float32)
    side = rng.integers(0, 2, (n, 3)).astype(bool)  # below or above zero per axis
    mag = rng.uniform(0.5, 2.0, (n, 3)).astype(np.float32)
    zero = np.where(rng.integers(0, 2, (n, 3)).astype(bool), np.float32(-0.0), np.float32(0.0))
    b[:, :3] = np.where(side, zero, -mag)
    b[:, 3:] = np.where(side, mag, zero)
    return b


def huge_tiny(n: int, seed: int = 1) -> np.ndarray:
    """Coordinates up to +-FLT_MAX and near 1e-30, and subnormals."""
    rng = np.random.default_rng(seed)
    scale = rng.choice([F32_MAX, 1e30, 1.0, 1e-30, 1e-40], size=(n, 1))
    lo = rng.uniform(-1, 1, (n, 3)) * scale
    size = rng.uniform(0, 1, (n, 3)) * scale
    b = np.empty((n, 6), np.float32)
    b[:, :3] = lo
    b[:, 3:] = np.minimum(lo + size, F32_MAX)  # stays finite
    b[:, 3:] = np.maximum(b[:, 3:], b[:, :3])
    return b


def dense(n: int, seed: int = 1) -> np.ndarray:
    """Each box overlapping ~10% of the others."""
    return uniform_density(n, seed, max(0.1 * n, 8.0))


SCENES = {
    "uniform": uniform_density,
    "heavy_tailed": heavy_tailed,
    "touching": touching,
    "same_x": same_x,
    "nested": nested,
    "identical": identical,
    "points_planes": points_planes,
    "signed_zero": signed_zero,
    "huge_tiny": huge_tiny,
    "dense": dense,
}


def brute_pairs(boxes: np.ndarray, chunk: int = 256) -> np.ndarray:
    """The oracle: Algorithm 1 in NumPy, every pair tested in float32 with closed intervals,
    (k, 2) uint32 sorted by (i, j)."""
    b = np.asarray(boxes, dtype=np.float32).reshape(-1, 6)
    n = len(b)
    lo, hi = b[:, :3], b[:, 3:]
    found = []
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        hit = np.all(
            (lo[start:stop, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[start:stop, None, :]),
            axis=2,
        )
        i, j = np.nonzero(hit)
        i = i + start
        keep = i < j
        found.append(np.stack([i[keep], j[keep]], axis=1))
    if not found:
        return np.empty((0, 2), np.uint32)
    return np.concatenate(found).astype(np.uint32)
