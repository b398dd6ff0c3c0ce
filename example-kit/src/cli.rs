//! The arguments every example shares (`--quick`, `--out DIR`), as a `clap` argument group an
//! example flattens into its own arguments:
//!
//! ```
//! use clap::Parser;
//!
//! /// An example.
//! #[derive(clap::Parser)]
//! struct Args {
//!     #[command(flatten)]
//!     common: example_kit::cli::Common,
//!     /// An example's own option.
//!     #[arg(long)]
//!     par: bool,
//! }
//!
//! let args = Args::parse_from(["example", "--quick", "--par"]);
//! assert!(args.common.quick && args.par && args.common.out.is_none());
//! ```

use std::path::PathBuf;

/// `--quick` and `--out DIR`.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct Common {
    /// Small CI-sized run (under a minute) instead of the full-size workload.
    #[arg(long)]
    pub quick: bool,
    /// Folder for the example's pictures and files (default: out/NAME, NAME the example).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// The arguments of an example that has no options of its own.
#[derive(clap::Parser, Debug, Clone)]
pub struct Args {
    /// The shared options.
    #[command(flatten)]
    pub common: Common,
}
