"""Writes the icospheres of scenes/examples/press_sphere.ron and grip_sphere.ron: radius 6 mm,
3 subdivisions (642 vertices), centred at (10, 10, -6.5) (top 0.5 mm below the sheet), 3 mm
higher, and 3 mm higher turned by 2 degrees about the y axis through its centre (its top moves
0.21 mm towards +x)."""
import math, os

def icosphere(levels):
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    v = [tuple(c / math.sqrt(sum(x * x for x in p)) for c in p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
         (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        mid, nf = {}, []
        def m(a, b):
            k = (min(a, b), max(a, b))
            if k not in mid:
                p = [(v[a][i] + v[b][i]) / 2 for i in range(3)]
                n = math.sqrt(sum(x * x for x in p))
                v.append(tuple(x / n for x in p))
                mid[k] = len(v) - 1
            return mid[k]
        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return v, f

v, f = icosphere(3)
here = os.path.dirname(os.path.abspath(__file__))
def turned(p, degrees):
    a = math.radians(degrees)
    return (math.cos(a) * p[0] + math.sin(a) * p[2], p[1], -math.sin(a) * p[0] + math.cos(a) * p[2])

for name, cz, turn in [("sphere.obj", -6.5, 0), ("sphere_up.obj", -3.5, 0), ("sphere_turned.obj", -3.5, 2)]:
    with open(os.path.join(here, name), "w") as out:
        out.write("# icosphere, radius 6 mm, made by make_sphere.py\n")
        for p in v:
            p = turned(p, turn) if turn else p
            out.write("v %.9f %.9f %.9f\n" % (10 + 6 * p[0], 10 + 6 * p[1], cz + 6 * p[2]))
        for a, b, c in f:
            out.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))
