#!/usr/bin/env python3
"""Checks a skinsim USD cache with Pixar's own reader (usd-core) against the OBJ export of the
same run (`skinsim run --export usd --export obj`).

usage: usd_check.py <out>/skinsim.usdc (or .usda) <out>/obj

For every Mesh prim: its patch and layer (the prims' customData names) have an OBJ folder with
one file per time sample, the first the rest state at frame 0; at each sample the points, faces
and normals match the OBJ's to float32 precision, and st the OBJ's vt (material coordinates, m)
divided by the prim's stMetres, or, for a character's layers, the asset's UVs (one per point,
finite); Mesh prim names are unique in the stage; the stage's time codes span the frames. Prints
one line per prim (its path, patch/layer, samples, whether its topology is time-sampled and st's
range); exit 0 when all match, 1 on a mismatch, 2 when usd-core is missing or the inputs are
unreadable.
"""

import math
import os
import sys


def read_obj(path):
    v, vt, vn, f = [], [], [], []
    with open(path) as fh:
        for line in fh:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                v.append(tuple(float(x) for x in w[1:4]))
            elif w[0] == "vt":
                vt.append(tuple(float(x) for x in w[1:3]))
            elif w[0] == "vn":
                vn.append(tuple(float(x) for x in w[1:4]))
            elif w[0] == "f":
                f.append(tuple(int(c.split("/")[0]) - 1 for c in w[1:4]))
    return v, vt, vn, f


def max_diff(a, b):
    return max((abs(x - y) for p, q in zip(a, b) for x, y in zip(p, q)), default=0.0)


def main(argv):
    if len(argv) != 3:
        print("usage: usd_check.py <stage.usda> <obj folder>", file=sys.stderr)
        return 2
    try:
        from pxr import Usd, UsdGeom
    except ImportError:
        print("error: usd-core is not installed (python3 -m pip install usd-core)", file=sys.stderr)
        return 2
    stage_path, obj_dir = argv[1], argv[2]
    stage = Usd.Stage.Open(stage_path)
    if stage is None:
        print(f"error: {stage_path}: USD cannot open it", file=sys.stderr)
        return 2
    bad = []
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    if not meshes:
        bad.append("no Mesh prim")
    frames = set()
    names = [p.GetName() for p in meshes]
    if len(set(names)) != len(names):
        bad.append(f"Mesh prim names repeat: {sorted(names)}")
    for prim in meshes:
        mesh = UsdGeom.Mesh(prim)
        patch = prim.GetParent().GetCustomDataByKey("name")
        layer = prim.GetCustomDataByKey("name")
        folder = os.path.join(obj_dir, patch, layer)
        objs = sorted(f for f in os.listdir(folder) if f.endswith(".obj")) if os.path.isdir(folder) else []
        times = mesh.GetPointsAttr().GetTimeSamples()
        if [int(o[:-4]) for o in objs] != [int(t) for t in times]:
            bad.append(f"{patch}/{layer}: time samples {times} but OBJ frames {objs}")
            continue
        worst, topology, uv_ok, normals_ok = 0.0, True, True, True
        lo, hi = [math.inf] * 2, [-math.inf] * 2
        st = UsdGeom.PrimvarsAPI(prim).GetPrimvar("st")
        # A character's layers carry the asset's own UVs in st (the OBJ's vt holds material
        # coordinates): check them as UVs of the right count instead.
        asset_st = (prim.GetCustomDataByKey("st") == "asset")
        unit = prim.GetCustomDataByKey("stMetres") or 1.0
        if times and int(times[0]) != 0:
            bad.append(f"{patch}/{layer}: the first sample is frame {times[0]}, not the rest state at 0")
        for t, o in zip(times, objs):
            frames.add(int(t))
            v, vt, vn, f = read_obj(os.path.join(folder, o))
            points = mesh.GetPointsAttr().Get(t)
            normals = mesh.GetNormalsAttr().Get(t)
            if len(points) != len(v) or len(normals) != len(v):
                bad.append(f"{patch}/{layer} frame {t}: {len(points)} points, {len(normals)} normals, OBJ {len(v)}")
                break
            normals_ok &= len(vn) == len(v) and max_diff(normals, vn) < 1e-5
            for p in st.Get(t):
                lo, hi = [min(a, b) for a, b in zip(lo, p)], [max(a, b) for a, b in zip(hi, p)]
            scale = max((abs(x) for p in v for x in p), default=1.0)
            worst = max(worst, max_diff(points, v) / max(scale, 1e-300))
            counts = mesh.GetFaceVertexCountsAttr().Get(t)
            indices = list(mesh.GetFaceVertexIndicesAttr().Get(t))
            flat = [i for face in f for i in face]
            topology &= list(counts) == [3] * len(f) and indices == flat
            if asset_st:
                uv_ok &= st.GetInterpolation() == "vertex" and len(st.Get(t)) == len(v) and all(
                    math.isfinite(x) for p in st.Get(t) for x in p)
            else:
                want = [(a / unit, b / unit) for a, b in vt]
                uv_ok &= st.GetInterpolation() == "vertex" and max_diff(st.Get(t), want) < 1e-6 * max(1.0, max((abs(x) for p in want for x in p), default=1.0))
        if worst > 1e-6:
            bad.append(f"{patch}/{layer}: points differ from the OBJ by {worst:.2e} of the extent")
        if not topology:
            bad.append(f"{patch}/{layer}: faces differ from the OBJ's")
        if not uv_ok:
            bad.append(f"{patch}/{layer}: st differs from the OBJ's vt")
        if not normals_ok:
            bad.append(f"{patch}/{layer}: normals differ from the OBJ's vn")
        sampled = bool(mesh.GetFaceVertexIndicesAttr().GetTimeSamples())
        print(f"{prim.GetPath()} ({patch}/{layer}): {len(times)} time samples, points within {worst:.1e} of the OBJ (relative), "
              f"faces {'match' if topology else 'DIFFER'}{' (topology time-sampled)' if sampled else ''}, "
              f"st in [{lo[0]:.6g}, {hi[0]:.6g}] x [{lo[1]:.6g}, {hi[1]:.6g}], "
              + (f"st the asset's UVs {'(finite, one per point)' if uv_ok else 'BAD'}" if asset_st
                 else f"st {'matches' if uv_ok else 'DIFFERS'}"))
    if frames and (stage.GetStartTimeCode() != min(frames) or stage.GetEndTimeCode() != max(frames)):
        bad.append(f"time codes {stage.GetStartTimeCode()}-{stage.GetEndTimeCode()}, frames {min(frames)}-{max(frames)}")
    print(f"stage {stage_path}: {len(meshes)} meshes, time codes {stage.GetStartTimeCode():g}-{stage.GetEndTimeCode():g} "
          f"at {stage.GetTimeCodesPerSecond():g} per second, up axis {UsdGeom.GetStageUpAxis(stage)}, "
          f"{UsdGeom.GetStageMetersPerUnit(stage):g} m per unit")
    for b in bad:
        print(f"mismatch: {b}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
