#!/usr/bin/env python3
"""The per-part table of the outside benchmark: each part of a preset turned off, against the recipe.

    python3 scripts/outside_parts.py BASELINE LABEL=STUDY [LABEL=STUDY+ ...] [--changed]

BASELINE and each STUDY are folders that `neus-aug study collect` wrote (`runs.csv` in them, or in
their `report/`). Every variant is compared with the baseline on the same runs (same scene and
seed): a variant run with seed 0 only is compared with the baseline's seed-0 runs.

A `+` after a folder (`stereo-off=results/outside-parts/no-stereo+`) fills the runs the variant
did not run with the baseline's own runs. That is for parts that act only on some meshes: the
stereo switch changes nothing on a run where it never fired (the check reads the field and keeps
no state), so only the runs where it fired are run again.

Aggregates are those of `study collect`'s suite line: the ratio to the floor is averaged over a
mesh's seeds, then the median and the worst are taken over meshes; the genus share counts runs
whose truth is known. The last columns pair the runs: the mean Chamfer difference (variant minus
recipe, mm), and how many runs got better or worse by more than 2 %. `--changed` also lists every
run whose Chamfer or genus changed.

Standard library only.
"""

import argparse
import csv
import statistics
import sys
from pathlib import Path


def load(folder: Path) -> dict[str, dict]:
    """Rows of `runs.csv` by run id."""
    for p in (folder / "runs.csv", folder / "report" / "runs.csv"):
        if p.is_file():
            with p.open(newline="") as f:
                return {r["id"]: r for r in csv.DictReader(f)}
    sys.exit(f"{folder}: no runs.csv (run `neus-aug study collect {folder}` first)")


def num(r: dict, key: str) -> float | None:
    v = r.get(key, "")
    try:
        x = float(v)
    except ValueError:
        return None
    return x if x == x else None  # NaN counts as missing


def aggregate(runs: list[dict]) -> dict:
    """The suite line over `runs`: median / worst / mean of per-mesh mean ratios, genus share."""
    by_scene: dict[str, list[float]] = {}
    right = known = 0
    for r in runs:
        ratio = num(r, "ratio_to_floor")
        if ratio is not None:
            by_scene.setdefault(r["scene"], []).append(ratio)
        if r.get("genus_matches") in ("true", "false"):
            known += 1
            right += r["genus_matches"] == "true"
    means = {s: statistics.fmean(v) for s, v in by_scene.items()}
    worst = max(means.items(), key=lambda kv: kv[1]) if means else ("—", float("nan"))
    return {
        "runs": len(runs),
        "median": statistics.median(means.values()) if means else float("nan"),
        "worst": worst,
        "mean": statistics.fmean(means.values()) if means else float("nan"),
        "right": right,
        "known": known,
    }


def row(label: str, a: dict, pair: str) -> str:
    w_scene, w = a["worst"]
    return (
        f"| {label} | {a['runs']} | {a['median']:.2f}× | {w:.2f}× (`{w_scene}`) | "
        f"{a['mean']:.2f}× | {a['right']} of {a['known']} | {pair} |"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("baseline", type=Path)
    ap.add_argument("variants", nargs="+", help="LABEL=STUDY, or LABEL=STUDY+ to fill from BASELINE")
    ap.add_argument("--changed", action="store_true", help="list the runs that changed")
    args = ap.parse_args()
    base = load(args.baseline)
    print("| variant | runs | median ratio | worst ratio | mean ratio | true genus | paired: Δ Chamfer (mm), better / worse by > 2 % |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    changed, shown = [], set()
    for spec in args.variants:
        label, sep, folder = spec.partition("=")
        if not sep:
            sys.exit(f"{spec}: expected LABEL=STUDY")
        fill = folder.endswith("+")
        var = load(Path(folder.rstrip("+")))
        if fill:
            seeds = {r["seed"] for r in var.values()} | {r["seed"] for r in base.values()}
            var = {**{k: r for k, r in base.items() if r["seed"] in seeds}, **var}
        ids = sorted(set(var) & set(base))
        missing = sorted(set(var) - set(base))
        if missing:
            print(f"warning: {label}: {len(missing)} runs without a baseline run: {missing[:3]}", file=sys.stderr)
        seeds = sorted({var[i]["seed"] for i in ids})
        b = aggregate([base[i] for i in ids])
        v = aggregate([var[i] for i in ids])
        diffs, better, worse = [], 0, 0
        for i in ids:
            cb, cv = num(base[i], "chamfer_sum"), num(var[i], "chamfer_sum")
            if cb is None or cv is None:
                continue
            diffs.append(cv - cb)
            better += cv < 0.98 * cb
            worse += cv > 1.02 * cb
            if args.changed and (abs(cv - cb) > 1e-9 or base[i]["genus"] != var[i]["genus"]):
                changed.append(
                    f"{label}: {i}: {cb:.3f} → {cv:.3f} mm, genus {base[i]['genus']} → "
                    f"{var[i]['genus']} (truth {var[i]['gt_genus']})"
                )
        pair = f"{statistics.fmean(diffs):+.3f}, {better} / {worse}" if diffs else "—"
        tag = f"seed{'s' if len(seeds) > 1 else ''} {', '.join(seeds)}"
        if (tag, len(ids)) not in shown:
            shown.add((tag, len(ids)))
            print(row(f"recipe ({tag})", b, "—"))
        print(row(f"{label} ({tag})", v, pair))
    for line in changed:
        print(line)


if __name__ == "__main__":
    main()
