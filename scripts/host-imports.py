#!/usr/bin/env python3
"""The host tools' module import graph (host-tools/src), and its circles; with `--core`,
the same for the no_std core (src/, without the firmware binary under src/bin/, which is
a crate of its own).

For every module that has child modules (the crate root, `slicer`, `serve`, ...) the graph
among its direct children: child A -> child B when a path in A's files (a `use`, or a
path written in the code such as `crate::slicer::toolpath::transit_mm` or, after
`use crate::slicer`, `slicer::toolpath::...`) names B or something inside B. A child's
own sub-modules count as the child (`slicer::gcode::exec` is `gcode` at `slicer`'s
level). A path to the parent itself (its `mod.rs`: its facade, its re-exports) is no
edge at this level. Unit-test modules (`#[cfg(test)] mod ... { }`) are left out: they
are not part of the layering. Paths are read from the text, not resolved by the
compiler: a glob import (`use x::*`) counts as an edge to `x`.

Prints each level's edges, then the circles (strongly connected parts of two or more
modules); `--check` prints only the circles and exits 1 if there is any.
`--core` reads src/ instead and also prints the crate level's layers (each module on the
first layer above everything it uses), the chain the core should read as.
Where it stops: it reads `use` trees and `a::b::c` paths; macros that build paths and
re-exports that hide where an item lives are read as written.
"""
import os
import re
import sys

from rust_text import code_only

HERE = os.path.dirname(os.path.abspath(__file__))
HOST = os.path.join(HERE, "..", "host-tools", "src")
CORE = os.path.join(HERE, "..", "src")


def module_files(root, skip=()):
    """{module path tuple: file} for every .rs file under root (lib.rs is the root),
    leaving out the top-level directories named in `skip`."""
    mods = {}
    for dirpath, _, files in os.walk(root):
        rel = os.path.relpath(dirpath, root)
        base = () if rel == "." else tuple(rel.split(os.sep))
        if base and base[0] in skip:
            continue
        for f in files:
            if not f.endswith(".rs"):
                continue
            if base == () and f == "main.rs":
                continue
            if f in ("mod.rs", "lib.rs"):
                mods[base] = os.path.join(dirpath, f)
            else:
                mods[base + (f[:-3],)] = os.path.join(dirpath, f)
    return mods


def strip(text):
    """The code without comments, string/char literals and `#[cfg(test)]` modules."""
    code = code_only(text)
    # Drop `#[cfg(test)] mod name { ... }` bodies.
    while True:
        m = re.search(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{", code)
        if not m:
            return code
        depth, j = 1, m.end()
        while j < len(code) and depth:
            depth += {"{": 1, "}": -1}.get(code[j], 0)
            j += 1
        code = code[: m.start()] + code[j:]


def use_paths(tree, prefix=()):
    """Expands a `use` tree (`crate::a::{self, b::c as d, e::*}`) into (path, alias)."""
    tree = tree.strip()
    depth = 0
    for k, ch in enumerate(tree):
        if ch == "{":
            if depth == 0:
                head = [s for s in tree[:k].strip().rstrip(":").split("::") if s]
                inner = tree[k + 1 : tree.rfind("}")]
                parts, d, start = [], 0, 0
                for q, ch2 in enumerate(inner):
                    if ch2 == "{":
                        d += 1
                    elif ch2 == "}":
                        d -= 1
                    elif ch2 == "," and d == 0:
                        parts.append(inner[start:q])
                        start = q + 1
                parts.append(inner[start:])
                res = []
                for p in parts:
                    if p.strip():
                        res += use_paths(p, prefix + tuple(head))
                return res
            depth += 1
    alias = None
    m = re.match(r"(.*)\s+as\s+(\w+)$", tree)
    if m:
        tree, alias = m.group(1).strip(), m.group(2)
    segs = tuple(s for s in tree.split("::") if s)
    if segs == ("self",):
        full = prefix
    else:
        full = prefix + segs
    if not full:
        return []
    if alias is None:
        alias = full[-1]
    return [(full, alias)]


def resolve(path, here, is_dir_mod, mods):
    """An absolute module path (tuple) for `path` written in module `here`, or None."""
    # The module paths are resolved against: a file `a/b.rs` is module a::b, and its
    # `super` is a; `a/mod.rs` is module a, and its `super` is the crate root's a's parent.
    cur = list(here)
    segs = list(path)
    if not segs:
        return None
    if segs[0] == "crate":
        return tuple(segs[1:])
    if segs[0] in ("self", "super"):
        base = cur
        while segs and segs[0] in ("self", "super"):
            if segs[0] == "super":
                base = base[:-1]
            segs = segs[1:]
        return tuple(base) + tuple(segs)
    # A child module of `here` named bare (2018 paths in a mod.rs or a file with children).
    if tuple(cur) + (segs[0],) in mods:
        return tuple(cur) + tuple(segs)
    return None


def module_of(abs_path, mods):
    """The longest module that is a prefix of abs_path."""
    for k in range(len(abs_path), -1, -1):
        if abs_path[:k] in mods:
            return abs_path[:k]
    return None


def references(mod, file, mods):
    code = strip(open(file, encoding="utf-8").read())
    is_dir = file.endswith(("mod.rs", "lib.rs"))
    aliases = {}
    found = set()
    for m in re.finditer(r"\buse\s+([^;]+);", code):
        for full, alias in use_paths(m.group(1)):
            if full[-1] == "*":
                full = full[:-1]
            a = resolve(full, mod, is_dir, mods)
            if a is None:
                continue
            found.add(a)
            aliases[alias] = a
    for m in re.finditer(r"(?<![\w:])((?:[A-Za-z_]\w*::)+[A-Za-z_]\w*)", code):
        segs = m.group(1).split("::")
        if segs[0] in aliases and segs[0] not in ("crate", "self", "super"):
            a = aliases[segs[0]] + tuple(segs[1:])
        else:
            a = resolve(tuple(segs), mod, is_dir, mods)
        if a is not None:
            found.add(a)
    targets = set()
    for a in found:
        t = module_of(a, mods)
        if t is not None:
            targets.add(t)
    return targets


def levels(mods, edges):
    """{parent: {child: set(children it uses)}} among each parent's direct children."""
    out = {}
    for src, dsts in edges.items():
        for dst in dsts:
            # The deepest common ancestor; the two children of it on each side.
            k = 0
            while k < min(len(src), len(dst)) and src[k] == dst[k]:
                k += 1
            if k == len(src) or k == len(dst):
                continue  # a module and its own ancestor or descendant: no edge
            parent = src[:k]
            a, b = src[: k + 1], dst[: k + 1]
            out.setdefault(parent, {}).setdefault(a, set()).add(b)
    return out


def circles(graph):
    """Tarjan's strongly connected components of two or more nodes."""
    index, low, stack, on, res = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
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
                res.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return res


def name(m):
    return "::".join(m) if m else "crate"


def layers(graph):
    """The modules of an acyclic graph by layer: a module sits one above the highest
    module it uses (leaves on layer 0)."""
    depth = {}

    def d(v):
        if v not in depth:
            depth[v] = 0  # a circle (reported apart) must not recurse forever
            depth[v] = 1 + max((d(w) for w in graph.get(v, ())), default=-1)
        return depth[v]

    for v in list(graph) + [w for ws in graph.values() for w in ws]:
        d(v)
    out = {}
    for v, k in depth.items():
        out.setdefault(k, []).append(v)
    return [sorted(out[k]) for k in sorted(out)]


def main():
    check = "--check" in sys.argv[1:]
    core = "--core" in sys.argv[1:]
    what = "the core (src)" if core else "host-tools"
    mods = module_files(CORE, skip=("bin",)) if core else module_files(HOST)
    edges = {m: references(m, f, mods) - {m} for m, f in mods.items()}
    found = []
    for parent, graph in sorted(levels(mods, edges).items()):
        if not check:
            print(f"{name(parent)}:")
            for a in sorted(graph):
                print(f"  {a[-1]} -> {', '.join(sorted(b[-1] for b in graph[a]))}")
        for c in circles(graph):
            found.append((parent, c))
    if core and not check and not any(parent == () for parent, _ in found):
        print("crate layers, lowest first:")
        for k, layer in enumerate(layers(levels(mods, edges).get((), {}))):
            print(f"  {k}: {', '.join(m[-1] for m in layer)}")
    if found:
        print(f"circles in {what}:")
        for parent, c in found:
            print(f"  in {name(parent)}: {' <-> '.join(x[-1] for x in c)}")
    else:
        print(f"no circles in {what}")
    return 1 if (check and found) else 0


if __name__ == "__main__":
    sys.exit(main())
