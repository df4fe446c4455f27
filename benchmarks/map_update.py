"""Time one UAV-step of onboard perception: scan + map integrate + 5 m sphere query.

Field: 40 x 30 x 10 m of random vertical cylinders at 0.2 m, the default SensorConfig (its rays and r_max are
printed with the result), UAVs flying straight through it. The same scans also go into octomap-python's
insertPointCloud for comparison (if installed). Target: scan + integrate + query << 0.3 ms.

    python benchmarks/map_update.py [--uavs 5] [--steps 300] [--repeats 3] [--seed 0]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from uavform_env.config import MapConfig, SensorConfig
from uavform_env.occupancy import MapStore
from uavform_env.sensing import STATIC, RangeSensor

RES = 0.2
SIZE = np.array([40.0, 30.0, 10.0])


def cylinder_field(rng: np.random.Generator, n: int = 80) -> np.ndarray:
    """uint8 grid of n vertical cylinders (radius 0.3-1.0 m, height 3-10 m); one numpy pass per cylinder."""
    shape = tuple(np.round(SIZE / RES).astype(int))
    occ = np.zeros(shape, np.uint8)
    xs = (np.arange(shape[0]) + 0.5) * RES
    ys = (np.arange(shape[1]) + 0.5) * RES
    zs = (np.arange(shape[2]) + 0.5) * RES
    for cx, cy, r, h in zip(rng.uniform(2, SIZE[0] - 2, n), rng.uniform(0, SIZE[1], n),
                            rng.uniform(0.3, 1.0, n), rng.uniform(3.0, 10.0, n)):
        disc = (xs[:, None] - cx) ** 2 + (ys[None, :] - cy) ** 2 <= r * r
        occ[disc[:, :, None] & (zs <= h)[None, None, :]] = 1
    return occ


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uavs", type=int, default=5)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3, help="fly the route this often; keep each step's fastest")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    occ = cylinder_field(rng)
    origin = np.zeros(3)
    sensor_cfg, map_cfg = SensorConfig(), MapConfig(resolution=RES)
    sensor = RangeSensor(sensor_cfg)
    # UAVs cross the field along x at spread-out heights and lanes (they fly through cylinders; the
    # sensor does not care, and it keeps every step's scan full of hits)
    start = np.column_stack([np.full(args.uavs, 1.0), np.linspace(3, SIZE[1] - 3, args.uavs),
                             np.linspace(1.5, 6.0, args.uavs)])
    yaws = np.zeros(args.uavs)
    velocity = np.array([38.0 / args.steps, 0.0, 0.0])

    def fly():
        """One pass over the route with fresh maps: per step (scan, integrate, query) seconds."""
        store = MapStore(origin, occ.shape, RES, map_cfg, args.uavs)
        maps = store.maps
        times, hits, occupied = [], [], []
        for k in range(args.steps):
            pos = start + k * velocity
            t0 = time.perf_counter()
            scan = sensor.scan(occ, origin, RES, pos, yaws, k, 0.3)
            t1 = time.perf_counter()
            store.integrate(np.arange(args.uavs), pos, scan.endpoints, scan.kind == STATIC)
            t2 = time.perf_counter()
            n_occ = sum(len(m.occupied_in_sphere(pos[i], 5.0)[0]) for i, m in enumerate(maps))
            t3 = time.perf_counter()
            times.append((t1 - t0, t2 - t1, t3 - t2))
            hits.append((scan.kind == STATIC).mean())
            occupied.append(n_occ / args.uavs)
        return np.array(times), np.mean(hits), np.mean(occupied)

    t = time.perf_counter()
    fly()  # numba compilation or cache load, then caches warm
    warmup = time.perf_counter() - t
    runs = [fly() for _ in range(args.repeats)]
    per_uav = np.min([r[0] for r in runs], axis=0) / args.uavs * 1e3  # ms per UAV-step, fastest repeat
    _, hits, occupied = runs[0]

    print(f"field {SIZE.tolist()} m at {RES} m: grid {occ.shape}, {occ.mean():.1%} occupied; "
          f"{args.uavs} UAVs x {args.steps} steps (fastest of {args.repeats} repeats per step); "
          f"{sensor_cfg.n_azimuth} x {sensor_cfg.n_elevation} rays, r_max {sensor_cfg.r_max} m; "
          f"static hits {hits:.0%} of rays; {occupied:.0f} occupied voxels within 5 m on average")
    print(f"first pass incl. numba compile / cache load: {warmup:.2f} s")
    print(f"{'ms per UAV-step':<28}{'median':>8}{'mean':>8}{'p95':>8}")
    for name, col in [("scan", per_uav[:, 0]), ("integrate", per_uav[:, 1]), ("occupied_in_sphere(5 m)", per_uav[:, 2]),
                      ("total", per_uav.sum(axis=1))]:
        print(f"{name:<28}{np.median(col):8.4f}{np.mean(col):8.4f}{np.percentile(col, 95):8.4f}")

    try:
        import octomap
    except ImportError:
        print("octomap-python not installed: no comparison")
        return
    trees = [octomap.OcTree(RES) for _ in range(args.uavs)]
    cost = []
    for k in range(args.steps):
        pos = start + k * velocity
        scan = sensor.scan(occ, origin, RES, pos, yaws, k, 0.3)
        for i, tree in enumerate(trees):  # max-range rays as far points, truncated by maxrange
            hit = scan.kind[i] == STATIC
            cloud = np.where(hit[:, None], scan.endpoints[i], pos[i] + scan.directions[i] * 2 * sensor_cfg.r_max)
            t0 = time.perf_counter()
            tree.insertPointCloud(cloud, pos[i], maxrange=sensor_cfg.r_max, lazy_eval=False, discretize=False)
            cost.append(time.perf_counter() - t0)
    cost = np.array(cost) * 1e3
    print(f"{'octomap insertPointCloud':<28}{np.median(cost):8.4f}{np.mean(cost):8.4f}{np.percentile(cost, 95):8.4f}"
          "   (same scans, one pass, one tree per UAV)")


if __name__ == "__main__":
    main()
