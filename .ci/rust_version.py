"""Fails when a package resolved for this platform needs a newer Rust than the workspace
declares (every member's `rust-version`). Reads `cargo metadata` JSON on stdin."""
import json
import sys


def key(version):
    return tuple(int(x) for x in (version.split(".") + ["0", "0"])[:3])


meta = json.load(sys.stdin)
members = set(meta["workspace_members"])
resolved = {node["id"] for node in meta["resolve"]["nodes"]}
declared = {p["name"]: p.get("rust_version") for p in meta["packages"] if p["id"] in members}
missing = sorted(name for name, v in declared.items() if not v)
if missing:
    sys.exit("workspace members without rust-version: " + ", ".join(missing))
msrv = min(declared.values(), key=key)
newer = sorted(
    f"{p['name']} {p['version']} needs {p['rust_version']}"
    for p in meta["packages"]
    if p["id"] in resolved and p.get("rust_version") and key(p["rust_version"]) > key(msrv)
)
if newer:
    sys.exit(f"workspace rust-version {msrv} is too old for: " + "; ".join(newer))
print(f"rust-version {msrv}: every resolved package builds with it")
