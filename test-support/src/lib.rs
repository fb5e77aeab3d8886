//! What cogstep's test suites share, so that each helper is written once:
//! `tests/tests/*.rs` (the workspace behaviour tests) and `driver/tests/`
//! use it as a dev-dependency.
//!
//! In the order a test uses them:
//! - [`props`]: how many random cases a property runs (`COGSTEP_MODEL_CASES`),
//!   shared strategies, and the tally a model-based property closes with.
//! - [`hub`]: a hub with its trace on, axes wired three pins apart with their
//!   stop pins high.
//! - [`edges`]: steps and positions read back from a trace's pin edges.
//! - [`ledger`]: the step accounts' identity for an idle axis.
//! - [`status`]: polling an axis (any [`AxisContract`]) until a status holds.
//! - [`grbl`]: a grbl board (the board simulator's grbl dialect) on a
//!   pseudo-terminal, with its settings file.
//! - [`script`]: a board behind a script that prints its device path
//!   (`firmware/run-qemu`, `firmware/run-pico-sim`), its control lines,
//!   stopped when dropped.
//! - [`pico`]: the Pico firmware's pins checked edge by edge: its axis
//!   cores replayed on the host, its VCD file read back.
//! - [`serial`]: a raw line client on a serial device (a board simulator's
//!   or QEMU's pseudo-terminal), and a symlink standing for a device path.
//!
//! Nothing here waits without a limit: every poll takes its patience and
//! fails with what it last saw.
//!
//! [`AxisContract`]: cogstep_motion::axis::AxisContract

pub mod edges;
pub mod grbl;
pub mod hub;
pub mod ledger;
pub mod pico;
pub mod props;
pub mod script;
pub mod serial;
pub mod status;
