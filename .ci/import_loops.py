#!/usr/bin/env python3
"""Fails when the modules of a crate import each other in a loop.

Within each crate, the children of every folder (its files and sub-folders) must form a
directed acyclic graph under the imports between them: `a.rs` may use `b.rs` or `b.rs` may use
`a.rs`, not both, directly or around a longer loop; likewise for folders (`camera/` and
`markers/` in one crate's `src/`). An import from a file in folder `x/` to a file in folder
`y/` is an edge between the siblings `x` and `y` of their common parent.

Imports are read from `use crate::…`, `use super::…` and `use self::…` statements (grouped
braces and `pub use` included) and from `crate::…` / `super::…` paths written inline in the
code. A name a module re-exports (`pub use child::Name`) is followed to the child that defines
it. Test code (`tests.rs`, modules named `tests`, and everything after a `#[cfg(test)]` module
in a file) is left out: a test may use its neighbours freely.

Usage: python3 .ci/import_loops.py [CRATE_DIR ...]  (default: every workspace member with a
`src/`, and the root package). Prints every loop and exits 1 if there is one.
"""

import os
import re
import sys

USE_RE = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", re.S | re.M)
INLINE_RE = re.compile(r"(?<![\w:])((?:crate|super|self)(?:::(?:super))*(?:::[A-Za-z_][A-Za-z0-9_]*)+)")
CFG_TEST_MOD_RE = re.compile(r"^\s*#\[cfg\(test\)\]\s*\n\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+\w+", re.M)


def strip_comments(text):
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    # String literals (no raw strings with quotes inside in this codebase's imports).
    return re.sub(r'"(?:\\.|[^"\\])*"', '""', text)


def module_of(src, path):
    rel = os.path.relpath(path, src)
    parts = rel[:-3].split(os.sep)
    if parts[-1] in ("mod", "lib", "main"):
        parts = parts[:-1]
    return tuple(parts)


def expand(tree):
    """`a::{b, c::{d, e}, self}` -> [a::b, a::c::d, a::c::e, a]."""
    tree = re.sub(r"\s+as\s+\w+", "", tree)
    tree = re.sub(r"\s+", "", tree)
    depth, start, items = 0, None, []
    for i, ch in enumerate(tree):
        if ch == "{":
            if depth == 0:
                start = i
            depth += 1
        elif ch == "}":
            depth -= 1
            if depth == 0:
                prefix = tree[:start].rstrip(":")
                inner, j, d, parts = tree[start + 1 : i], 0, 0, []
                for k, c in enumerate(inner):
                    if c == "{":
                        d += 1
                    elif c == "}":
                        d -= 1
                    elif c == "," and d == 0:
                        parts.append(inner[j:k])
                        j = k + 1
                parts.append(inner[j:])
                for p in parts:
                    if not p:
                        continue
                    if p == "self":
                        items.append(prefix)
                    else:
                        items.extend(expand(prefix + "::" + p))
                return items
    if tree.endswith("::*"):
        tree = tree[:-3]
    return [tree]


def absolute(module, is_folder, path):
    """The segments of `path` (crate/super/self-relative) from the crate root, or None."""
    segs = [s for s in path.split("::") if s]
    if not segs:
        return None
    if segs[0] == "crate":
        return segs[1:]
    # `self` is the module itself; `super` its parent. A folder's mod.rs is the folder.
    base = list(module)
    if segs[0] == "self":
        return base + segs[1:]
    if segs[0] == "super":
        while segs and segs[0] == "super":
            if not base:
                return None
            base = base[:-1]
            segs = segs[1:]
        return base + segs
    return None


def analyse(crate_dir):
    src = os.path.join(crate_dir, "src")
    files = {}
    for root, dirs, names in os.walk(src):
        dirs[:] = [d for d in dirs if d != "tests"]
        for n in names:
            if not n.endswith(".rs") or n == "tests.rs" or n == "main.rs":
                continue
            path = os.path.join(root, n)
            files[module_of(src, path)] = path
    modules = set(files)
    texts, reexports = {}, {}
    for m, path in files.items():
        with open(path, encoding="utf-8") as f:
            text = f.read()
        cut = CFG_TEST_MOD_RE.search(text)
        if cut:
            text = text[: cut.start()]
        text = strip_comments(text)
        texts[m] = text
        # Names this module re-exports from its children: name -> child module.
        exp = {}
        for stmt in USE_RE.finditer(text):
            full = stmt.group(0).lstrip()
            if not full.startswith("pub"):
                continue
            for p in expand(stmt.group(1)):
                segs = absolute(m, True, p) if p.split("::")[0] in ("crate", "self", "super") else list(m) + p.split("::")
                if not segs:
                    continue
                exp[segs[-1]] = tuple(segs)
        reexports[m] = exp

    def resolve(segs, seen=0):
        """The module a path refers to: its longest module prefix, followed through
        re-exports of the name after it."""
        segs = tuple(segs)
        for k in range(len(segs), -1, -1):
            if segs[:k] in modules:
                mod = segs[:k]
                if k < len(segs) and seen < 8:
                    target = reexports.get(mod, {}).get(segs[k])
                    if target and target[:-1] != mod and target != segs[: k + 1]:
                        return resolve(target + segs[k + 1 :], seen + 1)
                return mod
        return None

    edges = set()
    for m, text in texts.items():
        paths = []
        for stmt in USE_RE.finditer(text):
            paths.extend(expand(stmt.group(1)))
        body = USE_RE.sub("", text)
        paths.extend(x.group(1) for x in INLINE_RE.finditer(body))
        for p in paths:
            head = p.split("::")[0]
            if head not in ("crate", "super", "self"):
                continue
            segs = absolute(m, True, p)
            if segs is None:
                continue
            t = resolve(segs)
            if t is None or t == m:
                continue
            # Siblings under the common parent.
            k = 0
            while k < min(len(m), len(t)) and m[k] == t[k]:
                k += 1
            if k == len(m) or k == len(t):
                continue  # one contains the other (a folder's mod.rs and its children)
            edges.add((m[: k + 1], t[: k + 1]))
    return edges


def cycles(edges):
    graph = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
        graph.setdefault(b, set())
    found, state, stack = [], {}, []

    def visit(v):
        state[v] = 1
        stack.append(v)
        for w in sorted(graph[v]):
            if state.get(w) == 1:
                found.append(stack[stack.index(w) :] + [w])
            elif w not in state:
                visit(w)
        stack.pop()
        state[v] = 2

    for v in sorted(graph):
        if v not in state:
            visit(v)
    return found


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    crates = sys.argv[1:]
    if not crates:
        crates = [root] + sorted(
            os.path.join(root, d)
            for d in os.listdir(root)
            if os.path.isfile(os.path.join(root, d, "Cargo.toml"))
            and os.path.isdir(os.path.join(root, d, "src"))
        )
    bad = 0
    for c in crates:
        for loop in cycles(analyse(c)):
            bad += 1
            name = os.path.relpath(c, root) if c != root else "(root package)"
            print(f"{name}: import loop: " + " -> ".join("::".join(x) or "crate" for x in loop))
    if bad:
        print(f"{bad} import loop(s); the files and folders of each crate must form a DAG")
        return 1
    print("no import loops")
    return 0


if __name__ == "__main__":
    sys.exit(main())
