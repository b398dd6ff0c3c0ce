#!/usr/bin/env bash
# Laplacian editing factor + solve against the peers (CHOLMOD, SciPy splu), in one run on this
# machine, on the identical level-5 icosphere problem of ../shared/bench/peers/laplacian.py.
# Needs the peers' virtualenv (see ../shared/bench/peers/README.md). Not part of CI.
set -euo pipefail
cd "$(dirname "$0")/.."
peers=$(cd ../shared/bench/peers && pwd)
py=$peers/.venv/bin/python
cargo build --release --example laplacian_edit >/dev/null
rust=$(target/release/examples/laplacian_edit 2>/dev/null | tail -1)
cholmod=$(cd $peers && $py laplacian.py --variant cholmod | tail -1)
splu=$(cd $peers && $py laplacian.py --variant splu | tail -1)
python3 - "$rust" "$cholmod" "$splu" <<'PY'
import json, sys
rust, cholmod, splu = (json.loads(a) for a in sys.argv[1:])
ours = rust["lsq_factor_ms"] + rust["lsq_solve_ms"]
out = {"rust_factor_plus_solve_ms": ours}
for name, peer in (("cholmod", cholmod), ("splu", splu)):
    ph = peer["phases"]
    theirs = (ph["factor"] + ph["solve3"]) * 1e3
    out[f"{name}_factor_plus_solve_ms"] = theirs
    out[f"speedup_vs_{name}"] = theirs / ours
out["rust_objective"] = rust.get("objective")
out["cholmod_energy"] = cholmod["quality"]["energy"]
print(json.dumps(out))
PY
