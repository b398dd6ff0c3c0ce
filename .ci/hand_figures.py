#!/usr/bin/env python3
"""README.md's figures come from the records: fails on a number with a unit (mm, °, %, fps, s,
×, MB, GB, ms) outside the block that `cargo run --release --example results` generates.
ALLOW lists constants of the papers and of the setup that are not measured figures."""
import re, sys

UNIT = re.compile(r"(?<![\w.])\d[\d,.]*\s?(mm|°|%|fps|s|×|MB|GB|ms|µs|Hz|px)(?![\w])")
# Constants stated by the papers or the setup, not measurements.
ALLOW = ["286 Hz", "20 s", "1200 px"]

text = open("README.md", encoding="utf-8").read()
begin = text.find("<!-- results:begin")
end = text.find("<!-- results:end -->")
if begin < 0 or end < begin:
    print("README.md lacks its generated results block"); sys.exit(1)
outside = text[:begin] + text[end:]
bad = []
for i, line in enumerate(outside.splitlines(), 1):
    for m in UNIT.finditer(line):
        if m.group(0) not in ALLOW:
            bad.append(f"README.md: '{m.group(0)}' in: {line.strip()[:100]}")
for b in bad:
    print(b)
if bad:
    print(f"{len(bad)} hand-typed figure(s) in README.md: put figures in the generated block "
          "(results/ records) or, for a constant of a paper, in ALLOW in .ci/hand_figures.py")
    sys.exit(1)
print("no hand-typed figures in README.md")
