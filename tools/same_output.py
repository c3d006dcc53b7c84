#!/usr/bin/env python3
"""No-behaviour-change check: runs scenes spanning every element kind with two skinsim binaries
(--threads 2, OBJ frames exported) and compares, per scene, each frame's stats.jsonl line with
the timings removed (`timings_ms`, `solve_breakdown_ms`) and the SHA-256 of every OBJ frame.

    python3 tools/same_output.py OLD_BINARY NEW_BINARY --out DIR

Exit 0 when every scene is bit-identical. Two scenes are variants made on the fly: the two-layer
fig. 6-3 quick scene with quadratic bending (`element: Quadratic`, its Gaussian term) and the
volume slab example with cells (`poisson: 0.495, volume_element: Cell`)."""
import argparse, hashlib, json, pathlib, re, subprocess, sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
S = ROOT / "scenes"
# (scene, frames): shells with hinges and the quadratic plate, tets and cells, kernels, anchors,
# remeshing (settle, region solve), implicit Euler, attachments, periodic seams, bodies, glTF.
SCENES = [
    (S / "lk14/fig6_3_two_layers_quick.ron", 6), ("quadratic", 4), (S / "h15/patch_3d_small.ron", 5),
    ("cells", 6), (S / "h15/film_substrate_1000.ron", 4), (S / "kck18/crease_quick.ron", 6),
    (S / "kck18/creature_quick.ron", 5), (S / "lk14/remesh_one_layer_quick.ron", 6),
    (S / "examples/dynamic_strip.ron", 12), (S / "multi_patch.ron", 4),
    (S / "character/curved_sheet_quick.ron", 4), (S / "character/forehead_quick.ron", 2),
    (S / "lk14/fig6_4_pinch_remesh.ron", 2), (S / "kck18/self_intersect_quick.ron", 6),
    (S / "lk14/fig6_4_twist_quick.ron", 3), (S / "kck18/elbow_bending_quick.ron", 6),
    (S / "h15/exp3_two_layers.ron", 4),
]
VARIANTS = {
    "quadratic": (S / "lk14/fig6_3_two_layers_quick.ron",
                  "bending: Some((model: Tan))", "bending: Some((model: Tan, element: Quadratic))"),
    "cells": (S / "examples/volume_slab.ron",
              "poisson: 0.45, density: 1100.0)", "poisson: 0.495, density: 1100.0, volume_element: Cell)"),
}


def scene_path(scene, out):
    if scene not in VARIANTS:
        return scene
    base, old, new = VARIANTS[scene]
    text = base.read_text()
    assert old in text, f"{base}: the variant's anchor text is gone"
    # (neither base reads an asset: the variant runs from the output folder)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{scene}.ron"
    path.write_text(text.replace(old, new))
    return path


def digest(run):
    lines = []
    for line in (run / "stats.jsonl").read_text().splitlines():
        lines.append(re.sub(r'"(timings_ms|solve_breakdown_ms)":\{[^}]*\}', "", line))
    for obj in sorted(run.glob("obj/**/*.obj")):
        lines.append(f"{obj.relative_to(run)} {hashlib.sha256(obj.read_bytes()).hexdigest()}")
    return lines


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    out = pathlib.Path(a.out)
    failed = 0
    for scene, frames in SCENES:
        path = scene_path(scene, out)
        name = pathlib.Path(path).stem
        result = []
        for tag, binary in (("old", a.old), ("new", a.new)):
            run = out / tag / name
            cmd = [binary, "run", str(path), "--frames", str(frames), "--out", str(run), "--no-rerun",
                   "--quiet", "--threads", "2", "--export", "obj"]
            code = subprocess.run(cmd, capture_output=True).returncode
            result.append((code, digest(run) if code == 0 else None))
        (c0, d0), (c1, d1) = result
        same = c0 == c1 == 0 and d0 == d1
        failed += not same
        detail = f"{len(d1)} lines" if d1 else f"exit {c0} / {c1}"
        if not same and d0 and d1:
            detail = f"{sum(x != y for x, y in zip(d0, d1)) + abs(len(d0) - len(d1))} of {len(d1)} lines differ"
        print(f"{name:32} {'identical' if same else 'DIFFERENT'} ({detail})", flush=True)
    print(f"{len(SCENES) - failed} of {len(SCENES)} scenes bit-identical")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
