"""The peer of `benches/wall.rs`: the same running-bond wall of bricks in pymunk (Chipmunk2D).

Usage: python3 benches/peer_pymunk.py NX NY WARMUP STEPS THREADS DT GAP
Prints one JSON line: bodies, steps, threads and the median time per body-step (µs) of three
rounds of STEPS steps after WARMUP steps. GAP (m) separates the bricks and the rows.
Chipmunk is an impulse solver (10 iterations a step, its default); it is timed per body-step
at the same Δt as rbsm's penalty contact, on as many threads.
"""
import json
import sys
import time

import pymunk

W, H, T, RHO, G = 0.2, 0.1, 0.1, 1850.0, 9.80665


def wall(nx, ny, threads, gap):
    space = pymunk.Space(threaded=threads > 1)
    if threads > 1:
        space.threads = threads
    space.gravity = (0.0, -G)
    ground = pymunk.Segment(space.static_body, (-1.0, 0.0), (nx * W + 1.0, 0.0), 0.0)
    ground.friction = 0.5
    space.add(ground)
    mass = RHO * W * H * T
    moment = pymunk.moment_for_box(mass, (W, H))
    for j in range(ny):
        for i in range(nx):
            body = pymunk.Body(mass, moment)
            body.position = (i * (W + gap) + (0.25 * W if j % 2 else 0.0) + 0.5 * W, gap + j * (H + gap) + 0.5 * H)
            box = pymunk.Poly.create_box(body, (W, H))
            box.friction = 0.5
            space.add(body, box)
    return space


def main():
    nx, ny, warmup, steps, threads = (int(a) for a in sys.argv[1:6])
    dt, gap = float(sys.argv[6]), float(sys.argv[7])
    space = wall(nx, ny, threads, gap)
    for _ in range(warmup):
        space.step(dt)
    times = []
    for _ in range(3):
        start = time.perf_counter()
        for _ in range(steps):
            space.step(dt)
        times.append((time.perf_counter() - start) / (steps * nx * ny) * 1e6)
    print(json.dumps({"bodies": nx * ny, "steps": steps, "threads": threads, "us_per_body_step": sorted(times)[1],
                      "pymunk": pymunk.version}))


main()
