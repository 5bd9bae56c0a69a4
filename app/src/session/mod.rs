//! A session: a source, its calibration's view and the processing
//! pipeline on them, as the window and the headless modes run one; and
//! what a session records and replays.
//!
//! | module | what it holds |
//! | --- | --- |
//! | [`sources`] | `SourceSpec` (the simulated rig, live cameras, a recording, a bracket sequence) and starting a session on each |
//! | [`start`] | `Session` (the running pipeline, its record slot, the replay's control) and `start_session`, the start every source shares |
//! | [`view`] | the view of a calibration for a source's cameras (surround view or panorama), loading a calibration, the panorama's corner detector |
//! | [`record`] | `RecordSpec` and `RecordSlot`: the recording a session's pipeline hands its sets to |
//! | [`replay`] | a recording as the source, under the window's control |
//! | [`control`] | `ReplayControl`, the window's hold on a replay |
//! | [`capture`] | the sources `rigview record` opens to capture without processing |
//! | [`brackets`] | exposure brackets: their folder, `BracketSource`, their emulation, export and capture |
//!
//! The files import one way: `sources` → `replay` → `start` → `record`
//! and `control`; `view`, `record` and `control` import no sibling.

pub mod brackets;
pub mod capture;
pub mod control;
pub mod record;
pub mod replay;
pub mod sources;
pub mod start;
pub mod view;

pub use control::ReplayControl;
pub use record::{describe, RecordSlot, RecordSpec};
pub use replay::ReplaySpec;
pub use sources::{start, start_recording, BracketSpec, SimSpec, SourceSpec, BRACKETS_START};
pub use start::{Origin, Session};
pub use view::{canvas_spec, load_calibration, view_for, view_of, BuiltView};
