#!/usr/bin/env python3
"""Imports a skinsim USD cache into Blender 4.5 and sets what Blender's USD importer leaves out.

usage:
  python3 tools/blender_import.py <out>/skinsim.usdc [--save scene.blend]     (PyPI `bpy`)
  blender -b -P tools/blender_import.py -- <out>/skinsim.usdc [--save scene.blend]

Blender 4.5's USD importer reads the stage's frame range but not its rate: a 30 fps stage
opens at 24 fps whatever its timeCodesPerSecond and framesPerSecond say (measured on
bpy 4.5.15). This script imports the stage (mesh-sequence caches, UVs, normals), then sets the
scene's fps from the stage's timeCodesPerSecond, read from the file itself (the `.usda` text, or
the `.usdc` through Blender's bundled `pxr` where there is one), and prints a JSON summary:
the objects (named after the mesh prims, `<patch>_<layer>`), the fps, the frame range and each
mesh's UV range at the current frame. Exit 0 on success, 2 when the stage cannot be read.
"""

import json
import os
import re
import sys


def stage_rate(path):
    """The stage's timeCodesPerSecond (24 when it states none, as USD defaults)."""
    try:
        from pxr import Usd

        stage = Usd.Stage.Open(path)
        if stage is not None:
            return float(stage.GetTimeCodesPerSecond())
    except ImportError:
        pass
    if path.endswith(".usda"):
        with open(path, encoding="utf-8", errors="replace") as fh:
            head = fh.read(4096)
        m = re.search(r"timeCodesPerSecond\s*=\s*([0-9.eE+-]+)", head)
        if m:
            return float(m.group(1))
    return 24.0


def main(argv):
    args = argv[argv.index("--") + 1:] if "--" in argv else argv[1:]
    save = None
    if "--save" in args:
        i = args.index("--save")
        save = args[i + 1]
        args = args[:i] + args[i + 2:]
    if len(args) != 1 or not os.path.isfile(args[0]):
        print(__doc__, file=sys.stderr)
        return 2
    path = os.path.abspath(args[0])
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.wm.usd_import(filepath=path, set_frame_range=True, read_mesh_uvs=True)
    if "FINISHED" not in result:
        print(f"error: Blender could not import {path}", file=sys.stderr)
        return 2
    scene = bpy.context.scene
    rate = stage_rate(path)
    # Blender keeps fps as an integer over a base: 29.97 is 30 / 1.001.
    scene.render.fps = max(1, round(rate))
    scene.render.fps_base = scene.render.fps / rate
    objects = {}
    for ob in bpy.data.objects:
        if ob.type != "MESH":
            continue
        me = ob.data
        uv = me.uv_layers.active
        lo, hi = [float("inf")] * 2, [float("-inf")] * 2
        if uv is not None:
            for d in uv.data:
                lo = [min(a, b) for a, b in zip(lo, d.uv)]
                hi = [max(a, b) for a, b in zip(hi, d.uv)]
        objects[ob.name] = {
            "vertices": len(me.vertices),
            "uv_map": uv.name if uv is not None else None,
            "uv_range": [lo, hi] if uv is not None else None,
            "parent": ob.parent.name if ob.parent else None,
        }
    summary = {
        "stage": path,
        "fps": scene.render.fps / scene.render.fps_base,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "objects": objects,
    }
    print(json.dumps(summary, indent=1, sort_keys=True))
    if save:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(save))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
