#!/usr/bin/env python3
"""Mitsuba 3 baseline for the Kiln Cornell-box benchmark.

Renders /work/shared/reference-scenes/cornell-box/mitsuba3.xml at 256x256,
64 spp, max_depth 65 with Mitsuba 3 (llvm_ad_rgb and scalar_rgb) using 1 and
2 CPU threads, and prints one machine-readable line per configuration:

  mitsuba variant=V threads=N seconds=S samples_per_sec=X mean=r,g,b rmse=E ...

seconds is the median wall time of --repeats timed renders, taken after the
warm-up renders (so LLVM JIT compilation is not counted). The first (and
second) render times are printed separately on a `phase=warmup` line. Dr.Jit
specialises LLVM kernels on the thread count, so after each
dr.set_thread_count(n) one more untimed render is done (warmup_seconds=).
rmse is against TungstenRender.exr box-downsampled 4x4 to 256x256 (all
pixels, all three channels, linear radiance). It is dominated (>99% of the
squared error) by the few hundred pixels on the edge of the area light, where
the scene's tent filter at 256x256 blurs the 17/12/4 edge differently from a
4x4 box average of a 1024x1024 render, so it barely falls with spp.
rmse_nolight excludes reference pixels with max channel > 1 dilated by 2 px
(565 of 65536 pixels) and is noise-dominated.

Each variant runs in its own subprocess. For LLVM variants the Dr.Jit kernel
cache (normally ~/.drjit) is pointed at a fresh temporary directory, so the
first render includes a cold JIT compile; pass --warm-cache to use the
default on-disk cache instead.

Usage: python3 cornell.py [--variants llvm_ad_rgb,scalar_rgb] [--threads 1,2]
                          [--repeats 3] [--spp 64] [--res 256] [--warm-cache]
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

SCENE_DIR = "/work/shared/reference-scenes/cornell-box"
SCENE = os.path.join(SCENE_DIR, "mitsuba3.xml")
REFERENCE = os.path.join(SCENE_DIR, "TungstenRender.exr")
MAX_DEPTH = 65


def load_reference(mi, np, res):
    ref = np.array(mi.Bitmap(REFERENCE), dtype=np.float32)[..., :3]
    h, w, _ = ref.shape
    f = h // res
    assert h == w == res * f, (ref.shape, res)
    return ref.reshape(res, f, res, f, 3).mean(axis=(1, 3))


def light_mask(np, ref, radius=2):
    """Pixels showing the area light (reference max channel > 1), dilated."""
    m = ref.max(axis=-1) > 1.0
    out = m.copy()
    h, w = m.shape
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            out[max(dy, 0):h + min(dy, 0), max(dx, 0):w + min(dx, 0)] |= \
                m[max(-dy, 0):h + min(-dy, 0), max(-dx, 0):w + min(-dx, 0)]
    return out


def run_variant(args):
    # DRJIT_CACHE_DIR (if any) was set by the parent before this import.
    import mitsuba as mi
    import drjit as dr
    import numpy as np

    variant = args.variant
    mi.set_variant(variant)
    res, spp = args.res, args.spp
    samples = res * res * spp

    t0 = time.perf_counter()
    scene = mi.load_file(SCENE, resx=res, resy=res, spp=spp, max_depth=MAX_DEPTH)
    load_s = time.perf_counter() - t0
    ref = load_reference(mi, np, res)
    mask = light_mask(np, ref)  # 565 of 65536 pixels at 256x256

    def render():
        c0 = os.times()
        t = time.perf_counter()
        img = mi.render(scene, seed=0)
        dr.eval(img)
        dr.sync_thread()  # LLVM kernels run asynchronously
        wall = time.perf_counter() - t
        c1 = os.times()
        cpu = (c1.user + c1.system) - (c0.user + c0.system)
        return wall, cpu, np.array(img, dtype=np.float32)[..., :3]

    def stats(img):
        mean = img.reshape(-1, 3).mean(axis=0)
        se = (img.astype(np.float64) - ref) ** 2
        rmse = float(np.sqrt(np.mean(se)))
        rmse_nolight = float(np.sqrt(np.mean(se[~mask])))
        return mean, rmse, rmse_nolight

    default_threads = dr.thread_count()
    # Warm-up: LLVM compiles one kernel set on the first render and a few more
    # small ones on the second, so do two warm-ups for JIT variants.
    n_warm = 2 if variant.startswith(("llvm_", "cuda_")) else 1
    warm = [render()[0] for _ in range(n_warm)]
    print(f"mitsuba variant={variant} phase=warmup threads={default_threads} "
          f"load_seconds={load_s:.3f} "
          + " ".join(f"render{i + 1}_seconds={w:.3f}" for i, w in enumerate(warm))
          + f" jit_cache={args.cache_state} loadavg={os.getloadavg()[0]:.2f}", flush=True)

    for n in args.threads:
        dr.set_thread_count(n)  # also sizes the pool used by scalar variants
        # LLVM kernels are specialised on the thread count: the first render
        # after set_thread_count() rebuilds the main kernel, so warm up again.
        rewarm = render()[0] if n_warm > 1 else None
        runs = [render() for _ in range(args.repeats)]
        walls = [r[0] for r in runs]
        cpus = [r[1] for r in runs]
        sec = statistics.median(walls)
        mean, rmse, rmse_nolight = stats(runs[-1][2])
        rw = f"warmup_seconds={rewarm:.3f} " if rewarm is not None else ""
        print(f"mitsuba variant={variant} threads={n} res={res}x{res} spp={spp} "
              f"max_depth={MAX_DEPTH} seconds={sec:.4f} "
              f"samples_per_sec={samples / sec:.0f} "
              f"mean={mean[0]:.5f},{mean[1]:.5f},{mean[2]:.5f} rmse={rmse:.5f} "
              f"rmse_nolight={rmse_nolight:.5f} "
              f"min_seconds={min(walls):.4f} {rw}cpu_seconds={statistics.median(cpus):.3f} "
              f"runs={','.join(f'{w:.3f}' for w in walls)} "
              f"loadavg={os.getloadavg()[0]:.2f}", flush=True)
    dr.set_thread_count(default_threads)


def main():
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--variants", default="llvm_ad_rgb,scalar_rgb")
    p.add_argument("--threads", default="1,2")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--warm-cache", action="store_true",
                   help="use the default Dr.Jit kernel cache instead of a fresh one")
    p.add_argument("--variant", help=argparse.SUPPRESS)  # internal: child mode
    p.add_argument("--cache-state", default="default", help=argparse.SUPPRESS)
    args = p.parse_args()
    args.threads = [int(x) for x in str(args.threads).split(",")]

    if args.variant:
        run_variant(args)
        return

    import mitsuba as mi
    import drjit as dr
    print(f"# mitsuba {mi.__version__} drjit {dr.__version__} "
          f"cpus={os.cpu_count()} loadavg={os.getloadavg()[0]:.2f} "
          f"available={','.join(mi.variants())}", flush=True)
    rc = 0
    for v in args.variants.split(","):
        env = dict(os.environ)
        cmd = [sys.executable, os.path.abspath(__file__), "--variant", v,
               "--threads", ",".join(map(str, args.threads)),
               "--repeats", str(args.repeats), "--spp", str(args.spp),
               "--res", str(args.res)]
        with tempfile.TemporaryDirectory(prefix="drjit-cache-") as cache:
            if v.startswith(("llvm_", "cuda_")) and not args.warm_cache:
                env["DRJIT_CACHE_DIR"] = cache
                cmd += ["--cache-state", "cold"]
            elif v.startswith(("llvm_", "cuda_")):
                cmd += ["--cache-state", "default"]
            else:
                cmd += ["--cache-state", "n/a"]
            rc |= subprocess.call(cmd, env=env)
    sys.exit(rc)


if __name__ == "__main__":
    main()
