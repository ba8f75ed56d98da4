"""The static-scene moving part against the paper's box cut on scripted kitchen openings (deploy/bench/motion.py).

    .venv/bin/python scripts/bench_motion.py record --split train --seeds 0-29 --cache /tmp/motion-cache
    .venv/bin/python scripts/bench_motion.py record --split train --assets ../shared/partnet-mobility-dev --cache ...
    .venv/bin/python scripts/bench_motion.py score --cache /tmp/motion-cache --split train --out train.json

`record` makes the scripted openings (drawers and doors; with --assets every drawer and door part of every object
there, as the target of a kitchen) and keeps them in the cache; an episode the scripted generator cannot make is
listed with its reason. `score` scores every cached episode of the split and prints the summary as JSON.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path


def _seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def record(args: argparse.Namespace) -> None:
    from deploy.bench.motion_record import record_motion

    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    for name, task, seed, part, furniture in _jobs(args):
        path = cache / f"{args.split}-{name}.npz"
        if path.exists():
            continue
        try:
            episode = record_motion(task, seed, args.split, part=part, target_furniture=furniture,
                                    source=name.rsplit("-", 1)[0])
        except Exception as exc:  # the generator's one-line reasons (grasp failed, out of reach, ...)
            print(f"{name}: not recorded: {type(exc).__name__}: {exc}", file=sys.stderr)
            continue
        episode.save(path)
        print(f"{name}: {len(episode.depth_mm)} frames, opened {episode.joint_value[-1]:.3f}", file=sys.stderr)


def _jobs(args: argparse.Namespace):
    """(name, task, seed, part, furniture) of every episode to record."""
    if args.assets is None:
        for seed in _seeds(args.seeds):
            for task in args.tasks.split(","):
                yield f"{task}-{seed}", task, seed, None, None
        return
    from sim_fallback.partnet import load_partnet
    from sim_fallback.partnet.layout import object_folders

    for folder in object_folders(Path(args.assets)):
        furniture = load_partnet(folder)
        for k, part in enumerate(furniture.parts):
            yield f"partnet{folder.name}-{part.kind}{k}", part.kind, k, part.name, furniture


def score(args: argparse.Namespace) -> None:
    from deploy.bench.motion import score_episode, summarise
    from deploy.bench.motion_record import MotionEpisode

    paths = sorted(Path(args.cache).glob(f"{args.split}-*.npz"))
    results = []
    for k, path in enumerate(paths):
        print(f"scoring {path.name} ({k + 1}/{len(paths)})", file=sys.stderr)
        results.append(score_episode(MotionEpisode.load(path)))
    summary = summarise(results)
    text = json.dumps({"summary": summary, "episodes": results} if args.full else summary, indent=1)
    if args.out:
        Path(args.out).write_text(text + "\n")
    print(json.dumps(summary, indent=1))


def main() -> None:
    logging.basicConfig(level=logging.WARNING)
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record")
    rec.add_argument("--split", default="train")
    rec.add_argument("--seeds", default="0-29")
    rec.add_argument("--tasks", default="drawer,door")
    rec.add_argument("--assets", default=None)
    rec.add_argument("--cache", required=True)
    sc = sub.add_parser("score")
    sc.add_argument("--split", default="train")
    sc.add_argument("--cache", required=True)
    sc.add_argument("--out", default=None)
    sc.add_argument("--full", action="store_true", help="with every episode's per-frame figures")
    args = parser.parse_args()
    {"record": record, "score": score}[args.command](args)


if __name__ == "__main__":
    main()
