#!/usr/bin/env python3
"""Loads a neus-aug checkpoint with the `safetensors` Python package (numpy back end) and checks it
against the run's config.toml: every parameter group, both AdamW moments and the occupancy grid
are present with consistent shapes, the metadata's format/step are right, parameters are finite,
and the hash-grid table has the size the config implies. Prints a one-line summary; exits
non-zero on any problem.

usage: check_checkpoint.py RUN_DIR [--expect-step N]
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _pyenv  # noqa: E402

_pyenv.ensure({"numpy": "numpy", "safetensors": "safetensors"})

import argparse  # noqa: E402
import json  # noqa: E402
import tomllib  # noqa: E402

import numpy as np  # noqa: E402
from safetensors import safe_open  # noqa: E402
from safetensors.numpy import load_file  # noqa: E402

GROUPS = ["hash_grid", "sdf_mlp", "color_mlp", "variance", "appearance"]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("run_dir")
    ap.add_argument("--expect-step", type=int)
    args = ap.parse_args()
    run = Path(args.run_dir)
    cfg = tomllib.loads((run / "config.toml").read_text())
    path = run / "checkpoint.safetensors"
    tensors = load_file(str(path))
    with safe_open(str(path), framework="numpy") as f:
        meta = f.metadata()
    problems = []
    if meta.get("format") != "neus-aug-checkpoint-1":
        problems.append(f"format is {meta.get('format')!r}")
    if args.expect_step is not None and int(meta["step"]) != args.expect_step:
        problems.append(f"step {meta['step']} != {args.expect_step}")
    n_params = 0
    for g in GROUPS:
        p = tensors.get(f"params.{g}")
        if p is None:
            problems.append(f"params.{g} missing")
            continue
        n_params += p.size
        for m in ("adam_m", "adam_v"):
            t = tensors.get(f"{m}.{g}")
            if t is None or t.shape != p.shape or t.dtype != np.float32:
                problems.append(f"{m}.{g} missing or of another shape")
        if not np.all(np.isfinite(p)):
            problems.append(f"params.{g} has non-finite values")
    hg = cfg["model"]["field"]["hash_grid"]
    table = tensors.get("params.hash_grid")
    if table is not None and table.size > hg["n_levels"] * (2 ** hg["log2_hashmap_size"]) * hg["n_features_per_level"]:
        problems.append(f"hash table of {table.size} values exceeds L·T·F")
    occ = tensors.get("occupancy.occ")
    res = cfg["model"]["render"]["occupancy"]["resolution"]
    if occ is None or occ.shape != (res, res, res):
        problems.append(f"occupancy grid is not {res}³")
    if tensors.get("occupancy.binary", np.zeros(0)).dtype != np.uint8:
        problems.append("occupancy.binary is not uint8")
    var = tensors.get("params.variance")
    inv_s = float(np.exp(10.0 * var.ravel()[0])) if var is not None else float("nan")
    print(json.dumps({"step": int(meta["step"]), "params": int(n_params), "inv_s": inv_s, "tensors": len(tensors)}))
    if problems:
        print("PROBLEMS:\n" + "\n".join(problems), file=sys.stderr)
        return 1
    print("OK: checkpoint loads in Python and matches config.toml")
    return 0


if __name__ == "__main__":
    sys.exit(main())
