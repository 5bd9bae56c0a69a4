//! What the window runs on short-lived threads of their own, so that it
//! never waits: the native file dialog, and a view (a calibration file's,
//! or another view of the calibration in use) being built.

use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver};

use anyhow::Result;
use rigview_core::pipeline::ViewKind;

use super::messages::Messages;
use crate::session::BuiltView;

/// A view built in the background, or why not.
pub type Loaded = Result<BuiltView>;

/// What is being built in the background.
#[derive(Clone, Debug, PartialEq)]
pub enum Loading {
    /// A calibration file and its view.
    Calibration(PathBuf),
    /// Another view of the calibration in use.
    View(ViewKind),
}

/// What a file dialog is picking.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pick {
    /// A calibration to open.
    Calibration,
    /// A recording to replay.
    Recording,
    /// Where to save the panorama's refined rig.
    SaveRig,
}

/// The dialog open and the view being built, if any.
#[derive(Debug, Default)]
pub struct Background {
    loading: Option<(Loading, Receiver<Loaded>)>,
    dialog: Option<(Pick, Receiver<Option<PathBuf>>)>,
}

impl Background {
    /// Whether a view is being built.
    pub fn is_loading(&self) -> bool {
        self.loading.is_some()
    }

    /// Whether anything runs in the background (the window then repaints
    /// to follow it).
    pub fn is_busy(&self) -> bool {
        self.loading.is_some() || self.dialog.is_some()
    }

    /// Builds `what` with `build` on a thread of its own.
    pub fn build(
        &mut self,
        what: Loading,
        build: impl FnOnce() -> Loaded + Send + 'static,
        messages: &mut Messages,
    ) {
        let (tx, rx) = mpsc::channel();
        let spawned = std::thread::Builder::new()
            .name("rigview-view-build".into())
            .spawn(move || {
                let _ = tx.send(build());
            });
        match spawned {
            Ok(_) => self.loading = Some((what, rx)),
            Err(e) => messages.note(format!("cannot start building the view: {e}"), true),
        }
    }

    /// Opens the native file dialog for `pick` on a thread of its own.
    pub fn open_dialog(&mut self, pick: Pick, messages: &mut Messages) {
        let (tx, rx) = mpsc::channel();
        let spawned = std::thread::Builder::new()
            .name("rigview-dialog".into())
            .spawn(move || {
                let dialog = match pick {
                    Pick::Calibration => rfd::FileDialog::new()
                        .set_title("Open a rig or calibration file")
                        .add_filter("calibration", &["yaml", "yml", "xml", "json"]),
                    Pick::Recording => rfd::FileDialog::new()
                        .set_title("Open a recording")
                        .add_filter("recording (MCAP)", &["mcap"]),
                    Pick::SaveRig => rfd::FileDialog::new()
                        .set_title("Save the refined rig")
                        .set_file_name("refined.rig.yaml")
                        .add_filter("rig", &["yaml", "yml", "xml", "json"]),
                };
                let picked = match pick {
                    Pick::SaveRig => dialog.save_file(),
                    _ => dialog.pick_file(),
                };
                let _ = tx.send(picked);
            });
        match spawned {
            Ok(_) => self.dialog = Some((pick, rx)),
            Err(e) => messages.note(format!("cannot open the file dialog: {e}"), true),
        }
    }

    /// The file the dialog picked, once it has closed with one.
    pub fn poll_dialog(&mut self, messages: &mut Messages) -> Option<(Pick, PathBuf)> {
        let (pick, rx) = self.dialog.as_ref()?;
        let pick = *pick;
        match rx.try_recv() {
            Ok(Some(path)) => {
                self.dialog = None;
                Some((pick, path))
            }
            Ok(None) => {
                self.dialog = None;
                None
            }
            Err(mpsc::TryRecvError::Empty) => None,
            Err(mpsc::TryRecvError::Disconnected) => {
                self.dialog = None;
                messages.note(
                    "the file dialog failed (no desktop portal?): type the path under File instead"
                        .into(),
                    true,
                );
                None
            }
        }
    }

    /// The view built, once its thread is done (`None` inside: the thread
    /// ended without a result).
    pub fn poll_loading(&mut self) -> Option<(Loading, Option<Loaded>)> {
        let (what, rx) = self.loading.as_ref()?;
        let done = match rx.try_recv() {
            Ok(r) => Some((what.clone(), Some(r))),
            Err(mpsc::TryRecvError::Empty) => None,
            Err(mpsc::TryRecvError::Disconnected) => Some((what.clone(), None)),
        };
        if done.is_some() {
            self.loading = None;
        }
        done
    }
}
