#!/usr/bin/env python3
"""Text about the software only: fails on words that narrate how the work went.

Scans the library sources (*/src), docs/, examples/, tests/, README.md and ARCHITECTURE.md for
`session(s)`, `issue N`, `the issue('s)`, `we tried` and `the brief`. What changed and when belongs in commit
messages and CHANGELOG.md. ALLOW lists real uses (file, the matching text)."""
import os, re, sys

PATTERN = re.compile(
    r"\bsessions?\b|\bissue \d+|\bwe tried\b|\bthe brief\b|\bthe issue\b|\bissue's\b|\bissues'"
    r"|\bstudio issue\b|\bfollow-up issue\b",
    re.I,
)
ROOTS = ["docs", "examples", "tests", "README.md", "ARCHITECTURE.md"]
EXTS = (".rs", ".md", ".py", ".sh", ".toml")
# (path suffix, substring of the line) pairs that are not work history.
ALLOW = [
]

def files():
    for d in sorted(os.listdir(".")):
        src = os.path.join(d, "src")
        if os.path.isdir(src) and d not in ("target", "fuzz"):
            yield from walk(src)
    for r in ROOTS:
        if os.path.isfile(r):
            yield r
        elif os.path.isdir(r):
            yield from walk(r)

def walk(d):
    for base, dirs, names in os.walk(d):
        dirs[:] = sorted(x for x in dirs if x not in ("target", "out"))
        for n in sorted(names):
            if n.endswith(EXTS):
                yield os.path.join(base, n)

bad = []
for path in files():
    with open(path, encoding="utf-8", errors="replace") as f:
        for i, line in enumerate(f, 1):
            if PATTERN.search(line) and not any(
                path.endswith(p) and s in line for p, s in ALLOW
            ):
                bad.append(f"{path}:{i}: {line.strip()[:120]}")
for b in bad:
    print(b)
if bad:
    print(f"{len(bad)} line(s) narrate the work; say what the software does (history goes in "
          "commit messages and CHANGELOG.md), or add a real use to ALLOW in .ci/history_words.py")
    sys.exit(1)
print("no history words")
