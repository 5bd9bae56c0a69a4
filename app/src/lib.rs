//! `rigview` as a library: the parts of the application that tests and
//! other front ends use.
//!
//! - [`live`]: live capture from GenICam cameras through Aravis (the
//!   `aravis` feature, on by default), frame-set assembly, stream health and
//!   the `rigview live` command.

pub mod live;
