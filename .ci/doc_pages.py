#!/usr/bin/env python3
"""The reference pages under docs/: each under 40 KB, with its figures generated from the
records (a `<!-- figures:begin ... -->` block), and every relative link and picture it names
present in the repository (anchors aside)."""
import os, re, sys

LIMIT = 40 * 1024
PAGES = ["skin-core", "studio", "needle-model", "template-silhouette", "photometric-normals",
         "inertial-acoustic", "multilinear-face"]
LINK = re.compile(r"\]\(([^)\s]+)\)")

bad = []
for page in PAGES:
    path = os.path.join("docs", page + ".md")
    if not os.path.exists(path):
        bad.append(f"{path}: missing"); continue
    text = open(path, encoding="utf-8").read()
    size = len(text.encode("utf-8"))
    if size > LIMIT:
        bad.append(f"{path}: {size} bytes, over the {LIMIT}-byte limit of a reference page")
    if "<!-- figures:begin " not in text:
        bad.append(f"{path}: no generated figures block (<!-- figures:begin ... -->)")
    for target in LINK.findall(text):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        file = target.split("#", 1)[0]
        if file and not os.path.exists(os.path.normpath(os.path.join("docs", file))):
            bad.append(f"{path}: link to {target}, which does not exist")
for b in bad:
    print(b)
if bad:
    sys.exit(1)
print(f"{len(PAGES)} reference pages: sizes, figures blocks and links fine")
