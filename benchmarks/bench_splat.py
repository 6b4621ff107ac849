"""Benchmark of the Taichi splat renderer (fluidnexus.engine.splat.render) on a ScalarFlow-like plume.

Prints a markdown table: forward and forward+backward milliseconds (median of --repeats after warm-up) for
270x480 / 2 k, 270x480 / 20 k and 1080x1920 / 40 k Gaussians, and, in the same run, the dense torch
reference (tests/reference/splat_reference.py) on the smallest case with the speed ratio. A second table times
the same renders over a per-pixel background image (a clean plate, not optimised) against a constant one,
interleaved run by run in this process, with the ratio.

The scene imitates ScalarFlow: a camera 1.3 m from a rising plume (fx = 2614 px at 1080x1920), Gaussians in a
cone-shaped column 0.6 m tall, isotropic-ish scales 3-10 mm, opacities 0.05-0.3, grayscale (C = 1).

    python benchmarks/bench_splat.py [--arch cpu|cuda] [--precision f32|f64] [--repeats 5] [--channels 1]
                                     [--omp-wait active|passive] [--skip-reference] [--skip-plate]

On a CPU, torch's OpenMP threads spin after each torch op (OMP_WAIT_POLICY=active, libgomp's default) and
steal the cores from Taichi's kernels; ``--omp-wait passive`` (the default here) sets OMP_WAIT_POLICY=PASSIVE
before torch is imported. The table states which one was used.
"""
import argparse
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

CASES = [(270, 480, 2_000), (270, 480, 20_000), (1080, 1920, 40_000)]
PLUME = (0.34, 0.30, -0.225)  # ScalarFlow plume centre, metres


def plume_scene(n: int, channels: int, dtype, seed: int = 0):
    """n Gaussians in a widening column over the ScalarFlow source."""
    import torch

    gen = torch.Generator().manual_seed(seed)
    u = torch.rand(n, 4, generator=gen, dtype=torch.float64)
    height = 0.6 * u[:, 0]
    radius = (0.03 + 0.1 * height) * torch.sqrt(u[:, 1])
    angle = 2 * math.pi * u[:, 2]
    means = torch.stack([PLUME[0] + radius * torch.cos(angle), height, PLUME[2] + radius * torch.sin(angle)], 1)
    scales = 0.003 * torch.exp(torch.rand(n, 1, generator=gen, dtype=torch.float64) * math.log(10 / 3))
    scales = scales * (0.7 + 0.6 * torch.rand(n, 3, generator=gen, dtype=torch.float64))
    quats = torch.randn(n, 4, generator=gen, dtype=torch.float64)
    opacities = 0.05 + 0.25 * u[:, 3]
    colors = 0.5 + 0.4 * torch.rand(n, channels, generator=gen, dtype=torch.float64)
    return [t.to(dtype) for t in (means, scales, quats, opacities, colors)]


def plume_camera(width: int, height: int):
    """A ScalarFlow-like front camera, 1.3 m from the plume, at width x height."""
    from fluidnexus.camera import Camera

    eye = (PLUME[0], PLUME[1], PLUME[2] + 1.3)
    return Camera.look_at(1080, 1920, 2614.0, eye=eye, target=PLUME).resized(width, height)


def timed(fn, repeats: int, warmup: bool = True) -> tuple[float, float, float]:
    """Median and minimum wall time and mean process CPU time (all threads) of fn(), in milliseconds.

    The minimum and the CPU time are the figures to trust on a machine shared with other jobs.
    """
    if warmup:
        fn()
    times = []
    cpu0 = time.process_time()
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    cpu = (time.process_time() - cpu0) / repeats
    return 1e3 * statistics.median(times), 1e3 * min(times), 1e3 * cpu


def make_step(render, camera, inputs, background, backward: bool):
    def step():
        params = [t.detach().requires_grad_(backward) for t in inputs]
        image, alpha, _ = render(camera, *params, background)
        if backward:
            (image.sum() + alpha.sum()).backward()
    return step


def timed_pair(first, second, repeats: int) -> list[tuple[float, float]]:
    """Median wall time and median process CPU time (ms) of ``first()`` and of ``second()``, run alternately after
    one warm-up each, so that a change of load on a shared machine hits both alike."""
    first(), second()
    times = [([], []), ([], [])]
    for _ in range(repeats):
        for fn, (wall, cpu) in zip((first, second), times):
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            wall.append(1e3 * (time.perf_counter() - t0))
            cpu.append(1e3 * (time.process_time() - c0))
    return [(statistics.median(wall), statistics.median(cpu)) for wall, cpu in times]


def reference_step(camera, inputs, background, strip: int):
    """Dense reference forward+backward, in row strips of `strip` rows to bound memory."""
    from tests.reference.splat_reference import render_reference

    def step():
        params = [t.detach().requires_grad_(True) for t in inputs]
        for r0 in range(0, camera.height, strip):
            image, alpha, _ = render_reference(camera, *params, background,
                                               rows=(r0, min(camera.height, r0 + strip)))
            (image.sum() + alpha.sum()).backward()
    return step


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    parser.add_argument("--precision", default="f32", choices=["f32", "f64"])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--channels", type=int, default=1)
    parser.add_argument("--tile", type=int, default=16)
    parser.add_argument("--strip", type=int, default=32, help="rows per chunk of the dense reference")
    parser.add_argument("--skip-reference", action="store_true")
    parser.add_argument("--skip-plate", action="store_true", help="skip the per-pixel background comparison")
    parser.add_argument("--omp-wait", default="passive", choices=["active", "passive"])
    args = parser.parse_args()
    os.environ["OMP_WAIT_POLICY"] = args.omp_wait.upper()
    import torch

    from fluidnexus import engine

    engine.init(arch=args.arch, precision=args.precision)
    from fluidnexus.engine.splat import render
    from fluidnexus.engine.tensors import torch_device, torch_dtype

    dtype, dev = torch_dtype(), torch_device()
    background = torch.zeros(args.channels, dtype=dtype, device=dev)

    def rend(camera, *params):
        return render(camera, *params, tile=args.tile)

    print(f"# bench_splat: arch={args.arch} precision={args.precision} C={args.channels} tile={args.tile} "
          f"threads={torch.get_num_threads()} OMP_WAIT_POLICY={os.environ['OMP_WAIT_POLICY']} "
          f"{platform.processor() or platform.machine()} "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"load average at start: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print("| image (W x H) | Gaussians | forward ms (median / min) | forward+backward ms (median / min) "
          "| fwd+bwd CPU ms (all threads) |")
    print("|---|---|---|---|---|")
    small = None
    for width, height, n in CASES:
        camera = plume_camera(width, height)
        inputs = [t.to(dev) for t in plume_scene(n, args.channels, dtype)]
        fwd = timed(make_step(rend, camera, inputs, background, False), args.repeats)
        both = timed(make_step(rend, camera, inputs, background, True), args.repeats)
        print(f"| {width} x {height} | {n} | {fwd[0]:.1f} / {fwd[1]:.1f} | {both[0]:.1f} / {both[1]:.1f} "
              f"| {both[2]:.1f} |")
        small = small or (camera, inputs, both)
    if not args.skip_reference:
        camera, inputs, both = small
        ref = timed(reference_step(camera, [t.cpu() for t in inputs], background.cpu(), args.strip), 1, False)[0]
        print(f"\nDense torch reference, {camera.width} x {camera.height} / {inputs[0].shape[0]} Gaussians, "
              f"forward+backward: {ref:.0f} ms; Taichi (median) is {ref / both[0]:.0f}x faster.")
    if not args.skip_plate:
        print("\nPer-pixel background [H, W, C] (not optimised) against a constant one, forward+backward, runs "
              "interleaved:\n")
        print("| image (W x H) | Gaussians | constant: wall / CPU ms (medians) | per-pixel: wall / CPU ms (medians) "
              "| ratio per-pixel / constant: wall (CPU) |")
        print("|---|---|---|---|---|")
        for width, height, n in CASES:
            camera = plume_camera(width, height)
            inputs = [t.to(dev) for t in plume_scene(n, args.channels, dtype)]
            plate = torch.rand((height, width, args.channels), generator=torch.Generator().manual_seed(1),
                               dtype=torch.float64).to(device=dev, dtype=dtype)
            const, pixel = timed_pair(make_step(rend, camera, inputs, background, True),
                                      make_step(rend, camera, inputs, plate, True), args.repeats)
            print(f"| {width} x {height} | {n} | {const[0]:.1f} / {const[1]:.1f} | {pixel[0]:.1f} / {pixel[1]:.1f} "
                  f"| {pixel[0] / const[0]:.3f} ({pixel[1] / const[1]:.3f}) |")
    print(f"load average at end: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
