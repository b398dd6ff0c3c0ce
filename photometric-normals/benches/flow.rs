//! Times dense optical flow (`dense_flow`) on the flow workload of `bench/peers/flow.py`
//! (`peer_workloads::FlowWorkload`, 1024² as the peer's, or the sizes given) with the
//! accurate default and with `FlowParams::fast()`, and prints one JSON line per case: the
//! median wall and CPU seconds per pair over the runs (after one warm-up) and the mean
//! end-point errors, px. OpenCV's DIS medium on the same pair: `bench/peers/flow.py
//! --variant dis`.
//!
//! `cargo bench -p photometric-normals --features validation --bench flow [-- 512 1024]`

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // not library code

use std::time::Instant;

mod common;
use common::cpu_seconds;

use photometric_normals::peer_workloads::FlowWorkload;
use photometric_normals::{dense_flow, FlowParams};
use skin_core::stats::median;

/// Timed runs per case (after one warm-up).
const RUNS: usize = 7;

fn main() {
    let sizes: Vec<u32> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let sizes = if sizes.is_empty() { vec![1024] } else { sizes };
    for n in sizes {
        let w = FlowWorkload::new(n).unwrap();
        for (name, params) in [
            ("default", FlowParams::default()),
            ("fast", FlowParams::fast()),
        ] {
            let mut flow = dense_flow(&w.first, &w.second, &params).unwrap();
            let (mut wall, mut cpu) = (Vec::new(), Vec::new());
            for _ in 0..RUNS {
                let (t, c) = (Instant::now(), cpu_seconds());
                flow = dense_flow(&w.first, &w.second, &params).unwrap();
                wall.push(t.elapsed().as_secs_f64());
                cpu.push(cpu_seconds() - c);
            }
            let (epe, epe_interior) = w.epe(&flow).unwrap();
            println!(
                "{{\"size\":{n},\"params\":\"{name}\",\"wall_s\":{:.4},\"cpu_s\":{:.4},\
                 \"epe_px\":{epe:.4},\"epe_interior_px\":{epe_interior:.4}}}",
                median(&wall),
                median(&cpu)
            );
        }
    }
}
