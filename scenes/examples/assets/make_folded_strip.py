"""Writes the strip (with its unrolled texture coordinates) of scenes/examples/fold_strip.ron, already folded (mm): a lower ply along
x from 0 to 30 at z = 0, a half-circle fold of radius 1 about (30, z = 1), an upper ply back
to x = 10 at z = 2; 4 mm wide, about 1 mm cells. `folded_strip_pressed.obj` has the last
3 mm of the upper ply (x <= 13) moved 3 mm down; the scene holds those vertices, so that
blend shape carries them down through the lower ply."""
import math, os

def centreline():
    pts = [(float(x), 0.0) for x in range(0, 30)]                      # lower ply
    pts += [(30 + math.sin(math.pi * k / 6), 1 - math.cos(math.pi * k / 6)) for k in range(0, 7)]
    pts += [(float(x), 2.0) for x in range(29, 9, -1)]                 # upper ply
    return pts

line = centreline()
across = [0.0, 1.0, 2.0, 3.0, 4.0]
faces = []
n = len(across)
for i in range(len(line) - 1):
    for j in range(n - 1):
        a, b, c, d = i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1
        faces += [(a, b, c), (a, c, d)] if (i + j) % 2 == 0 else [(a, b, d), (b, c, d)]
here = os.path.dirname(os.path.abspath(__file__))
upper_end = len(line) - 4  # the last 4 centreline points: x = 13, 12, 11, 10 on the upper ply
for name, drop in [("folded_strip.obj", 0.0), ("folded_strip_pressed.obj", 3.0)]:
    with open(os.path.join(here, name), "w") as out:
        out.write("# a folded strip, made by make_folded_strip.py (mm)\n")
        for i, (x, z) in enumerate(line):
            for y in across:
                out.write("v %.9f %.9f %.9f\n" % (x, y, z - (drop if i >= upper_end else 0.0)))
        # texture coordinates: the unrolled strip (arc length along the centreline, y), mm
        s = 0.0
        for i, (x, z) in enumerate(line):
            if i > 0:
                s += math.hypot(x - line[i - 1][0], z - line[i - 1][1])
            for y in across:
                out.write("vt %.9f %.9f\n" % (s, y))
        for a, b, c in faces:
            out.write("f %d/%d %d/%d %d/%d\n" % (a + 1, a + 1, b + 1, b + 1, c + 1, c + 1))
