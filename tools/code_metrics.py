#!/usr/bin/env python3
"""The house's code figures (issue 63), for a checkout at ROOT (default: this one):
import circles between sibling files of a folder of src/ (a file's `super::x` or
`crate::<folder>::x` references outside tests), the library's pub items and how many of them no
other package names, the longest functions of src/, the largest files of src/solve/, and
`too_many_arguments` allowances.

    python3 tools/code_metrics.py [ROOT]"""
import os, re, sys

ROOT = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


def code(path):
    s = open(path).read()
    i = s.find("#[cfg(test)]")
    return s if i < 0 else s[:i]


def rust_files(top):
    for d, _, fs in os.walk(top):
        for f in sorted(fs):
            if f.endswith(".rs"):
                yield os.path.join(d, f)


def circles(src):
    found = []
    for d, dirs, files in os.walk(src):
        mods = {f[:-3] for f in files if f.endswith(".rs") and f != "mod.rs"}
        mods |= {x for x in dirs if os.path.exists(os.path.join(d, x, "mod.rs"))}
        rel = os.path.relpath(d, src).replace(os.sep, "::")
        edges = {m: set() for m in mods}
        for m in mods:
            paths = [os.path.join(d, m + ".rs")] if os.path.exists(os.path.join(d, m + ".rs")) else list(
                rust_files(os.path.join(d, m)))
            for p in paths:
                s = re.sub(r"//.*", "", code(p))
                up = "super::super::" if not p.endswith(m + ".rs") else "super::"
                for o in mods - {m}:
                    pats = [up + o + r"\b", up + r"\{[^}]*\b" + o + r"\b"]
                    if rel != ".":
                        pats.append(r"crate::" + rel + "::" + o + r"\b")
                    if any(re.search(q, s) for q in pats):
                        edges[m].add(o)
        index, low, stack, on, counter = {}, {}, [], set(), [0]

        def strong(v):
            index[v] = low[v] = counter[0]
            counter[0] += 1
            stack.append(v)
            on.add(v)
            for w in edges[v]:
                if w not in index:
                    strong(w)
                    low[v] = min(low[v], low[w])
                elif w in on:
                    low[v] = min(low[v], index[w])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append((os.path.relpath(d, src), sorted(comp)))

        for v in sorted(mods):
            if v not in index:
                strong(v)
    return found


def pub_items(root):
    items = []
    for p in rust_files(os.path.join(root, "src")):
        for m in re.finditer(r"^\s*pub\s+(?:(?:const|unsafe|async)\s+)*(fn|struct|enum|trait|const|type|static|mod)\s+(\w+)",
                             code(p), re.M):
            items.append(m.group(2))
    outside = ""
    for d in ("systems", "tools", "tests", "benches"):
        for p in rust_files(os.path.join(root, d)):
            outside += open(p).read()
    words = set(re.findall(r"\w+", outside))
    return len(items), sum(1 for n in items if n not in words)


def functions(top):
    out = []
    for p in rust_files(top):
        lines = open(p).read().split("\n")
        for i, line in enumerate(lines):
            m = re.match(r"\s*(pub(\([^)]*\))?\s+)?(const\s+)?fn\s+(\w+)", line)
            if not m:
                continue
            depth, started = 0, False
            for j in range(i, len(lines)):
                depth += lines[j].count("{") - lines[j].count("}")
                started |= "{" in lines[j]
                if started and depth <= 0:
                    out.append((j - i + 1, os.path.relpath(p, ROOT), m.group(4)))
                    break
                if not started and lines[j].rstrip().endswith(";"):
                    break
    return sorted(out, reverse=True)


src = os.path.join(ROOT, "src")
c = circles(src)
print(f"import circles in src: {len(c)}")
for d, comp in c:
    print(f"  {d}: {len(comp)} files: {' '.join(comp)}")
n, internal = pub_items(ROOT)
print(f"pub items in src (fn, struct, enum, trait, const, type, static, mod; outside tests): {n}; "
      f"named by no other package: {internal}")
print("longest functions in src:")
for f in functions(src)[:3]:
    print(f"  {f[0]} lines: {f[1]} {f[2]}")
sizes = sorted(((sum(1 for _ in open(p)), os.path.relpath(p, ROOT)) for p in rust_files(os.path.join(src, "solve"))),
               reverse=True)
print("largest files in src/solve: " + ", ".join(f"{p} {n}" for n, p in sizes[:2]))
allows = sum(open(p).read().count("too_many_arguments") for d in ("src", "systems", "tools", "tests", "benches")
             for p in rust_files(os.path.join(ROOT, d)))
print(f"too_many_arguments allowances: {allows}")
