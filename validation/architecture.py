#!/usr/bin/env python3
"""Import cycles and layer violations between the modules of src/ (issue 19): exits 1 if there is
one.

    python3 validation/architecture.py            # the cycles, or "no import cycles"
    python3 validation/architecture.py --edges    # also every module's dependencies

A module is a file (`core/src/io/formats/vdb.rs` is `io::formats::vdb`, `src/io/mod.rs` is `io`; the
physics crate's `core/src/` and `src/` are one tree, as `ohd` re-exports every module of ohd-core). Module A depends on
module B when A's code (comments, doc links and `#[cfg(test)]` modules left out) names a path into
B: a `use` of `crate::…`, `super::…`, `self::…` or of a child module, or an inline `crate::…` /
`super::…` path. A path is followed through modules and through `pub use` re-exports to the module
that defines the item (`crate::retrieval::FitOptions` is `retrieval::fit`); a path that ends in a
module is a dependency on that module. A module and its own ancestors or descendants are one
unit of the hierarchy (a parent re-exporting its children, a child using its parent's error
type): those edges are not counted. A cycle is a strongly connected component of two or more
modules; one shortest cycle through each of its modules is printed.

Layers: every module belongs to a layer of `LAYERS` (the architecture of src/lib.rs's docs, by the
longest matching prefix) and may depend only on modules of its own layer or of lower ones; an
edge upwards is printed as a violation, and a module in no layer is one too.
"""

import argparse
import re
import sys
from collections import deque
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"
# The physics crate `ohd-core` (core/src): `ohd` re-exports each of its modules under the same
# name, so the two crates are read as one tree of modules (the two `io` modules, the input side
# in ohd-core and the output side in ohd, as one).
CORE = SRC.parent / "core" / "src"


# The layers of src/, lowest first (src/lib.rs, "Architecture"): (name, module prefixes).
LAYERS = [
    ("foundations", ["error", "numeric", "sys", "sampling", "stats", "spectrum", "phase", "surface", "mie", "output", "retrieval"]),
    ("scene", ["medium", "flow", "source", "io::formats"]),
    ("recording", ["detect"]),
    ("transport", ["transport"]),
    ("runs", ["experiment", "pilot", "post", "scan", "converge", "describe"]),
    ("configuration", ["config"]),
    ("outputs", ["io::write", "io::persist", "io::figures", "io"]),
    ("orchestration", ["run"]),
    ("binary", ["cli"]),
]


def layer_of(mod):
    """Index into LAYERS of module `mod` (a tuple of segments): the longest prefix that matches."""
    best = None
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            segs = tuple(p.split("::"))
            if mod[: len(segs)] == segs and (best is None or len(segs) > best[1]):
                best = (i, len(segs))
    return None if best is None else best[0]


def module_of(path):
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("mod", "lib"):
        parts = parts[:-1]
    if parts == ["main"]:
        return None  # the binary's root, a crate of its own
    return tuple(parts)


def strip(text):
    """Remove comments, strings and `#[cfg(test)]` items (brace-matched)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            i = n if j < 0 else j + 2
        elif c == '"' or (c == "r" and re.match(r'r#*"', text[i:]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_"))):
            m = re.match(r'(r(#*))?"', text[i:])
            if m.group(1):
                end = '"' + m.group(2)
                j = text.find(end, i + len(m.group(0)))
                i = n if j < 0 else j + len(end)
            else:
                j = i + 1
                while j < n and text[j] != '"':
                    j += 2 if text[j] == "\\" else 1
                i = j + 1
            out.append('""')
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", text[i:]):
            i += len(re.match(r"'(\\.|[^\\'])'", text[i:]).group(0))
            out.append("' '")
        else:
            out.append(c)
            i += 1
    s = "".join(out)
    # Drop #[cfg(test)] items: from the attribute to the end of the item's braces or semicolon.
    while True:
        m = re.search(r"#\[cfg\(test\)\]", s)
        if not m:
            return s
        j = m.end()
        while j < len(s) and s[j] not in "{;":
            j += 1
        if j < len(s) and s[j] == "{":
            depth = 0
            while j < len(s):
                depth += s[j] == "{"
                depth -= s[j] == "}"
                j += 1
                if depth == 0:
                    break
        else:
            j += 1
        s = s[: m.start()] + s[j:]


def use_trees(s):
    """Every `use` declaration: (is_pub, [path segments lists])."""
    for m in re.finditer(r"(\bpub(\([^)]*\))?\s+)?\buse\s+([^;]+);", s):
        tree = re.sub(r"\s+as\s+\w+", "", m.group(3))
        yield bool(m.group(1)), list(expand(re.sub(r"\s+", "", tree)))


def expand(tree, prefix=()):
    """Paths of a use tree, `a::{b, c::{d, e as f}}` → a::b, a::c::d, a::c::e (as-names dropped)."""
    tree = tree.strip()
    if not tree:
        return
    depth, parts, cur = 0, [], ""
    i = tree.find("{")
    if i < 0:
        yield prefix + tuple(p for p in tree.split("::") if p)
        return
    head = tree[:i].rstrip(":")
    body = tree[i + 1 : tree.rfind("}")]
    head_segs = tuple(p for p in head.split("::") if p)
    for ch in body:
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    for p in parts:
        yield from expand(p, prefix + head_segs)


def main():
    global SRC
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--edges", action="store_true", help="print every module's dependencies")
    ap.add_argument("--src", type=Path, default=SRC, help="the crate's source directory (default: src/)")
    ap.add_argument("--core", type=Path, default=CORE, help="ohd-core's source directory (default: core/src/)")
    args = ap.parse_args()

    files = {}
    for root in (args.core.resolve(), args.src.resolve()):
        SRC = root
        for p in sorted(root.rglob("*.rs")):
            mod = module_of(p)
            if mod is not None:
                files[mod] = files.get(mod, "") + strip(p.read_text()) + "\n"
    modules = set(files)

    # `pub use` re-exports: (module, name) → the path it re-exports (absolute segments).
    def absolute(mod, segs):
        """Absolute module path segments of a path written in `mod`, or None if external."""
        if not segs:
            return None
        head = segs[0]
        if head == "crate":
            return list(segs[1:])
        if head == "self":
            return list(mod) + list(segs[1:])
        if head == "super":
            base = list(mod)
            k = 0
            while k < len(segs) and segs[k] == "super":
                base = base[:-1]
                k += 1
            return base + list(segs[k:])
        if tuple(mod) + (head,) in modules:
            return list(mod) + list(segs)
        return None

    reexports = {}
    for mod, s in files.items():
        for is_pub, paths in use_trees(s):
            if not is_pub:
                continue
            for segs in paths:
                a = absolute(mod, segs)
                if a and a[-1] not in ("*", "self"):
                    name = segs[-1]
                    reexports[(mod, name)] = a

    def resolve(path, seen=0):
        """The module defining the item at absolute `path` (a module path is that module)."""
        cur = ()
        for i, seg in enumerate(path):
            if seg in ("*", "self"):
                return cur
            if cur + (seg,) in modules:
                cur = cur + (seg,)
                continue
            r = reexports.get((cur, seg))
            if r is not None and seen < 20 and r != list(cur) + [seg]:
                return resolve(r + list(path[i + 1 :]), seen + 1)
            return cur
        return cur

    edges = {m: set() for m in modules}
    for mod, s in files.items():
        targets = []
        for _, paths in use_trees(s):
            for segs in paths:
                a = absolute(mod, segs)
                if a is not None:
                    targets.append(a)
        body = re.sub(r"(\bpub(\([^)]*\))?\s+)?\buse\s+[^;]+;", "", s)
        for m in re.finditer(r"\b(crate|super)((?:::\w+)+)", body):
            segs = [m.group(1)] + m.group(2).split("::")[1:]
            a = absolute(mod, segs)
            if a is not None:
                targets.append(a)
        for a in targets:
            t = resolve(a)
            if t == mod or t[: len(mod)] == mod or mod[: len(t)] == t:
                continue  # itself, a descendant or an ancestor
            edges[mod].add(t)

    name = lambda m: "::".join(m) if m else "crate"
    if args.edges:
        for m in sorted(edges, key=name):
            print(f"{name(m)} → {', '.join(sorted(map(name, edges[m]))) or '–'}")
        print()

    # Tarjan's strongly connected components.
    index, low, stack, on, sccs = {}, {}, [], set(), []
    counter = [0]

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
                sccs.append(sorted(comp, key=name))

    sys.setrecursionlimit(10000)
    for v in sorted(modules, key=name):
        if v not in index:
            strong(v)

    def shortest_cycle(v, comp):
        prev, q = {v: None}, deque([v])
        while q:
            u = q.popleft()
            for w in sorted(edges[u], key=name):
                if w not in comp:
                    continue
                if w == v:
                    path = [u]
                    while prev[path[-1]] is not None:
                        path.append(prev[path[-1]])
                    return list(reversed(path)) + [v]
                if w not in prev:
                    prev[w] = u
                    q.append(w)
        return None

    bad = 0
    for m in sorted(modules, key=name):
        if not m:
            continue
        lm = layer_of(m)
        if lm is None:
            print(f"module {name(m)} is in no layer of LAYERS")
            bad += 1
            continue
        for t in sorted(edges[m], key=name):
            lt = layer_of(t) if t else 0
            if lt is not None and lt > lm:
                print(f"layer violation: {name(m)} ({LAYERS[lm][0]}) → {name(t)} ({LAYERS[lt][0]})")
                bad += 1
    if not sccs:
        print("no import cycles" + ("" if bad else f"; every module within its layer ({len(LAYERS)} layers)"))
        return 1 if bad else 0
    for comp in sorted(sccs, key=lambda c: name(c[0])):
        cset = set(comp)
        print(f"cycle among {len(comp)} modules: {', '.join(map(name, comp))}")
        shown = set()
        for v in comp:
            c = shortest_cycle(v, cset)
            key = tuple(sorted(map(name, c[:-1])))
            if c and key not in shown:
                shown.add(key)
                print("    " + " → ".join(map(name, c)))
    return 1


if __name__ == "__main__":
    sys.exit(main())
