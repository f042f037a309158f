"""The paper's test scenario in NumPy, with bpx as the broad phase, drawn with matplotlib.

    pip install ./python matplotlib
    python python/examples/spheres.py [--spheres 500] [--cycles 600] [--out spheres.png]

Woulfe, Dingliana & Manzke (2007), section 5: spheres of radius 25 m in a closed box 400 m
high, laid out with 10 m gaps, each with its own random velocity in (-40, -40, -40) ..
(40, 40, 40) m/s, bouncing off each other and the walls (the choices of `bpx demo`,
docs/demo.md: one layer at mid-height, elastic, 1/60 s steps). Each cycle runs the paper's loop:
broad phase (bpx, the two phases: extents once, centres every cycle), narrow phase (centres at
most 2r apart), collision response (equal-mass elastic impulses, then the overlap pushed
apart), physics (positions, walls). The picture shows the last cycle from above, pairs bpx
reported drawn as lines, and the pairs per cycle.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import bpx

RADIUS, GAP, HEIGHT, SPEED, DT = 25.0, 10.0, 400.0, 40.0, 1.0 / 60.0


def initial_state(n: int, seed: int):
    """Positions on a near-square grid at mid-height with 10 m gaps; the box that fits them."""
    columns = math.ceil(math.sqrt(n))
    rows = math.ceil(n / columns)
    pitch = 2 * RADIUS + GAP
    k = np.arange(n)
    x = GAP + RADIUS + (k % columns) * pitch
    z = GAP + RADIUS + (k // columns) * pitch
    pos = np.stack([x, np.full(n, HEIGHT / 2), z], axis=1)
    size = np.array([columns * pitch + GAP, HEIGHT, rows * pitch + GAP])
    vel = np.random.default_rng(seed).uniform(-SPEED, SPEED, (n, 3))
    return pos, vel, size


def respond(pos, vel, pairs):
    """Narrow phase and response on bpx's pairs: contacts are centres at most 2r apart."""
    if len(pairs) == 0:
        return 0
    i, j = pairs[:, 0].astype(np.intp), pairs[:, 1].astype(np.intp)
    d = pos[j] - pos[i]
    dist = np.linalg.norm(d, axis=1)
    contact = (dist <= 2 * RADIUS) & (dist > 0)
    i, j, d, dist = i[contact], j[contact], d[contact], dist[contact]
    normal = d / dist[:, None]
    vn = np.einsum("ij,ij->i", vel[j] - vel[i], normal)
    approaching = vn < 0
    impulse = (vn * approaching)[:, None] * normal  # elastic, equal masses
    np.add.at(vel, i, impulse)
    np.add.at(vel, j, -impulse)
    push = ((2 * RADIUS - dist) * 0.5)[:, None] * normal  # positions only: no energy added
    np.add.at(pos, i, -push)
    np.add.at(pos, j, push)
    return int(contact.sum())


def step(pos, vel, size):
    """Physics: a sphere whose next step would cross a wall turns back on that axis now."""
    nxt = pos + vel * DT
    out = (nxt - RADIUS < 0) | (nxt + RADIUS > size)
    vel[out] = -vel[out]
    pos += vel * DT
    np.clip(pos, RADIUS, size - RADIUS, out=pos)


def main():
    parser = argparse.ArgumentParser(description="The paper's spheres through bpx")
    parser.add_argument("--spheres", type=int, default=500)
    parser.add_argument("--cycles", type=int, default=600)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--out", default="spheres.png")
    args = parser.parse_args()

    pos, vel, size = initial_state(args.spheres, args.seed)
    counts, contacts, broad_ns = [], [], []
    with bpx.World(backend=args.backend, track_events=True) as world:
        # Initialisation phase: every sphere's box centred at the origin, as its minima.
        world.load_extents(np.full((args.spheres, 3), -RADIUS, np.float32))
        for _ in range(args.cycles):
            start = time.perf_counter_ns()
            world.update_centres(pos.astype(np.float32))  # updating phase: 12 bytes a sphere
            pairs = world.collide()
            broad_ns.append(time.perf_counter_ns() - start)
            counts.append(len(pairs))
            contacts.append(respond(pos, vel, pairs))
            step(pos, vel, size)
        # The picture's pairs: those of the final positions.
        world.update_centres(pos.astype(np.float32))
        pairs = world.collide()
        began = len(world.events.began)
        stats = world.stats
    print(
        f"{args.spheres} spheres, {args.cycles} cycles: {sum(counts)} pairs in all "
        f"({max(counts)} at most per cycle), {sum(contacts)} contacts; broad phase "
        f"{np.median(broad_ns) / 1e3:.1f} us per cycle (median, Python included); "
        f"last cycle: {len(pairs)} pairs ({began} new), backend {stats.backend}"
    )
    draw(pos, pairs, counts, size, args)


def draw(pos, pairs, counts, size, args):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import Circle

    fig, (top, plot) = plt.subplots(
        1, 2, figsize=(12, 5.6), dpi=100, gridspec_kw={"width_ratios": [1.15, 1]}
    )
    paired = np.zeros(len(pos), bool)
    paired[pairs.ravel()] = True
    circles = [Circle((x, z), RADIUS) for x, _, z in pos]
    colours = np.where(paired, "#d62728", "#9ecae1")
    top.add_collection(PatchCollection(circles, facecolors=colours, edgecolors="#3b5b7a", lw=0.4))
    segments = [[(pos[i, 0], pos[i, 2]), (pos[j, 0], pos[j, 2])] for i, j in pairs]
    top.add_collection(LineCollection(segments, colors="black", linewidths=1.2))
    top.set_xlim(0, size[0])
    top.set_ylim(0, size[2])
    top.set_aspect("equal")
    top.set_xlabel("x (m)")
    top.set_ylabel("z (m)")
    top.set_title(
        f"{len(pos)} spheres after {args.cycles / 60:.0f} s, seen from above:\n"
        f"{len(pairs)} overlapping boxes (bpx pairs, lines, red)"
    )
    plot.plot(np.arange(len(counts)) * DT, counts, lw=0.8, color="#d62728")
    plot.set_xlabel("simulated time (s)")
    plot.set_ylabel("pairs per cycle (bpx)")
    plot.set_title("Broad-phase pairs per cycle, 1/60 s cycles")
    plot.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
