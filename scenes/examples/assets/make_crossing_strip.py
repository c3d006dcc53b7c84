"""Writes the upper strip of scenes/examples/two_strips.ron (mm): 20 mm along x from -8 to 12,
4 mm wide (y from 8 to 12), 1 mm cells, 1 mm above the lower strip (z = 1), and
`crossing_strip_pressed.obj`, its two end cells (|x - 2| >= 9) moved 2.5 mm down: the scene
holds those vertices, so that blend shape carries the strip's ends below the lower strip."""
import os

xs = [float(x) for x in range(-8, 13)]
ys = [8.0, 9.0, 10.0, 11.0, 12.0]
here = os.path.dirname(os.path.abspath(__file__))
for name, drop in [("crossing_strip.obj", 0.0), ("crossing_strip_pressed.obj", 2.5)]:
    with open(os.path.join(here, name), "w") as out:
        out.write("# a strip crossing above the lower one, made by make_crossing_strip.py (mm)\n")
        for x in xs:
            for y in ys:
                z = 1.0 - (drop if abs(x - 2.0) >= 9.0 else 0.0)
                out.write("v %.9f %.9f %.9f\n" % (x, y, z))
        for x in xs:
            for y in ys:
                out.write("vt %.9f %.9f\n" % (x + 8.0, y - 8.0))
        n = len(ys)
        for i in range(len(xs) - 1):
            for j in range(n - 1):
                a, b, c, d = i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j + 2, i * n + j + 2
                out.write("f %d/%d %d/%d %d/%d\n" % (a, a, b, b, c, c))
                out.write("f %d/%d %d/%d %d/%d\n" % (a, a, c, c, d, d))
