"""`raspv sim`: tools for world files and logged runs (no ROS needed).

    raspv sim check WORLD...                 validate world files, list their objects and classes
    raspv sim map WORLD -o DIR               occupancy map (map_server PGM + YAML) for planners
    raspv sim render WORLD -o OUT.png        the avatar's view (colour, depth, labels) and an overview
    raspv sim plot RUN_DIR                   summary and top-down trajectory of a logged run
    raspv sim walk WALK -o DIR               a simulated RGB-D walk with ground truth (TUM layout)
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="sim_command", metavar="TOOL", required=True)
    p = sub.add_parser("check", help="validate world files and list their contents")
    p.add_argument("worlds", nargs="+", metavar="WORLD", help="shipped world name or YAML path")
    p = sub.add_parser("map", help="write a world's occupancy map (PGM + YAML, map_server format)")
    p.add_argument("world", metavar="WORLD")
    p.add_argument("-o", "--output", default=".", metavar="DIR", help="directory for <world>.pgm/.yaml (default .)")
    p.add_argument("--resolution", type=float, default=0.05, help="metres per cell (default 0.05)")
    p.add_argument("--structure-only", action="store_true",
                   help="only walls, doors and stairs (the paper's building map; furniture left to the camera)")
    p.add_argument("--band", type=float, nargs=2, default=(0.05, 1.9), metavar=("LOW", "HIGH"),
                   help="heights above the floor that block a walker [m] (default 0.05 1.9)")
    p = sub.add_parser("render", help="render the avatar's view and a bird's-eye overview")
    p.add_argument("world", metavar="WORLD")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png",
                   help="view figure; the overview goes to OUT-overview.png")
    p.add_argument("--at", type=float, nargs=3, metavar=("X", "Y", "YAW_DEG"), help="avatar pose (default: spawn)")
    p.add_argument("--head", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("ROLL", "PITCH", "YAW"),
                   help="head angles relative to the base [deg] (pitch > 0 looks down)")
    p.add_argument("--size", default="640x480", help="camera resolution WxH (default 640x480)")
    p.add_argument("--renderer", choices=("auto", "egl", "tiny"), default="auto")
    p.add_argument("--time", type=float, default=0.0, help="sim time for the people's positions [s]")
    p = sub.add_parser("walk", help="render a walk (route, loops, kidnaps) as an RGB-D sequence with ground truth "
                                    "(TUM layout: rgb/, depth/, rgb.txt, depth.txt, groundtruth.txt)")
    p.add_argument("walk", metavar="WALK", help="a shipped walk (" + ", ".join(_shipped_walks()) + ") or a walk YAML")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="new folder for the sequence")
    p.add_argument("--perfect-depth", action="store_true", help="noise-free depth (default: the realistic sensor model)")
    p.add_argument("--flat", action="store_true", help="flat-coloured surfaces (default: surface textures)")
    p.add_argument("--size", help="camera resolution WxH (default: the walk's, 640x480)")
    p.add_argument("--loops", type=int, help="walk the route this many times (default: the walk's)")
    p = sub.add_parser("plot", help="summary and trajectory plot of a logged run (also after a kill)")
    p.add_argument("run_dir", metavar="RUN_DIR")
    p.add_argument("-o", "--output", metavar="OUT.png", help="default RUN_DIR/trajectory.png")


def run(args: argparse.Namespace) -> int:
    from raspv_sim.world_spec import WorldFileError

    try:
        return {"check": _check, "map": _map, "render": _render, "plot": _plot, "walk": _walk}[args.sim_command](args)
    except (WorldFileError, ValueError) as exc:
        print(f"raspv sim: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"raspv sim: {exc.filename or ''}: {exc.strerror}", file=sys.stderr)
        return 2


def _check(args) -> int:
    from raspv_sim.world_check import check_world
    from raspv_sim.world_spec import BUILTIN_CLASSES, WorldFileError

    bad = 0
    for name in args.worlds:
        try:
            w = check_world(name)          # the YAML, then built headless: meshes, people, spawn
        except WorldFileError as exc:
            print(f"error: {exc}")
            bad += 1
            continue
        extra = w.classes[len(BUILTIN_CLASSES):]
        print(f"ok: {w.name} ({w.source}): {len(w.walls)} walls, {len(w.furniture)} furniture, {len(w.models)} models, "
              f"{len(w.stairs)} staircases, {len(w.people)} people, {len(w.goals)} goals; "
              f"own classes: {', '.join(extra) if extra else 'none'}")
    return 2 if bad else 0


def _map(args) -> int:
    from raspv_common.occupancy import FREE, OCCUPIED, save_map
    from raspv_sim.occupancy_export import world_occupancy
    from raspv_sim.simulator import SimConfig, Simulation

    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    with Simulation(args.world, SimConfig(width=16, height=12, renderer="tiny")) as sim:
        grid = world_occupancy(sim.world, args.resolution, tuple(args.band), args.structure_only)
        path = out / f"{sim.spec.name}{'-structure' if args.structure_only else ''}.yaml"
    save_map(grid, path)
    free, occ = int((grid.cells == FREE).sum()), int((grid.cells == OCCUPIED).sum())
    print(f"{path} + {path.with_suffix('.pgm').name}: {grid.shape[1]}x{grid.shape[0]} cells at {grid.resolution} m, "
          f"origin {grid.origin}, {free} free, {occ} occupied")
    return 0


def _render(args) -> int:
    from raspv_sim.avatar import head_quaternion
    from raspv_sim.simulator import SimConfig, Simulation
    from raspv_sim.world_preview import overview_image, save_rgb, view_figure

    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        print(f"raspv sim render: --size must be WxH, e.g. 640x480, got {args.size!r}", file=sys.stderr)
        return 2
    out = Path(args.output)
    with Simulation(args.world, SimConfig(width=width, height=height, renderer=args.renderer)) as sim:
        if args.at:
            sim.avatar.teleport(args.at[0], args.at[1], math.radians(args.at[2]))
        sim.set_head(head_quaternion(*(math.radians(v) for v in args.head)))
        sim.step(args.time)
        frame = sim.render()
        a = sim.avatar
        title = (f"{sim.spec.name}: avatar at ({a.x:.2f}, {a.y:.2f}) m, yaw {math.degrees(a.yaw):.0f}°, "
                 f"{width}x{height}, {sim.renderer.description}")
        view_figure(frame, sim.classes, out, title)
        over = save_rgb(overview_image(sim), out.with_name(out.stem + "-overview.png"))
    print(f"{out}\n{over}")
    return 0


def _plot(args) -> int:
    from raspv_sim.experiment_log import summarize_run
    from raspv_sim.occupancy_export import world_occupancy
    from raspv_sim.simulator import SimConfig, Simulation
    from raspv_sim.trajectory_plot import plot_run

    run_dir = Path(args.run_dir)
    meta_file = run_dir / "meta.json"
    if not meta_file.is_file():
        print(f"raspv sim plot: {run_dir} is not a run directory (no meta.json)", file=sys.stderr)
        return 2
    try:
        meta = json.loads(meta_file.read_text())
        world = meta.get("world_file") or meta["world"]
    except (json.JSONDecodeError, KeyError, AttributeError):
        print(f"raspv sim plot: {meta_file} is not a run's meta.json (no world recorded)", file=sys.stderr)
        return 2
    with Simulation(world, SimConfig(width=16, height=12, renderer="tiny")) as sim:
        grid = world_occupancy(sim.world)
    png = plot_run(run_dir, grid, args.output)
    print(json.dumps(summarize_run(run_dir), indent=2))
    print(png)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="raspv sim", description=__doc__.strip().splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())


def _shipped_walks() -> list[str]:
    return sorted(p.stem for p in (Path(__file__).parent / "walks").glob("*.yaml"))


def _walk(args) -> int:
    import dataclasses

    from raspv_sim.walks import load_walk, render_walk

    path = Path(args.walk)
    if not path.suffix and not path.exists():
        path = Path(__file__).parent / "walks" / f"{args.walk}.yaml"
        if not path.is_file():
            raise ValueError(f"no walk {args.walk!r}: give a walk YAML or one of {', '.join(_shipped_walks())}")
    spec = load_walk(path)
    changes = {"realistic_depth": not args.perfect_depth, "textures": not args.flat}
    if args.size:
        try:
            w, h = (int(v) for v in args.size.lower().split("x"))
        except ValueError:
            raise ValueError(f"--size must be WxH, e.g. 640x480, got {args.size!r}") from None
        changes.update(width=w, height=h)
    if args.loops is not None:
        changes["loops"] = args.loops
    spec = dataclasses.replace(spec, **changes)
    out = Path(args.output)
    if out.exists() and any(out.iterdir()):
        raise ValueError(f"{out}: folder exists and is not empty")
    tty = sys.stderr.isatty()

    def progress(done: int, total: int) -> None:
        if tty and (done % 10 == 0 or done == total):
            print(f"\rrendering {done}/{total}", end="", file=sys.stderr, flush=True)

    plan = render_walk(spec, out, progress)
    if tty:
        print(file=sys.stderr)
    print(f"{out}: {len(plan.poses)} frames, {plan.length_m:.1f} m walked in {spec.world}, "
          f"back at the start at {', '.join(f'{t:.1f}' for t in plan.loop_times)} s"
          + (f", {len(spec.kidnaps)} kidnap(s)" if spec.kidnaps else "")
          + f"; import it: raspv bag from-frames {out} -o BAG")
    return 0
