//! The window's messages: the events that reached the app's
//! [`LogBuffer`] since the window opened (the last few kept), and the
//! pipeline's own messages and problems passed on as events.

use rigview_core::pipeline::PipelineStatus;

use crate::logging::{LogBuffer, StatusLog};

/// A message shown in the window: an event that reached the app's
/// [`LogBuffer`].
#[derive(Clone, Debug)]
pub struct Message {
    /// The text.
    pub text: String,
    /// A problem (red: a warning or an error) or a note.
    pub error: bool,
}

/// Messages the window keeps.
const MESSAGES: usize = 20;

/// The messages the window shows, read from the log.
#[derive(Debug)]
pub struct Messages {
    list: Vec<Message>,
    log: LogBuffer,
    seen: u64,
    status_log: StatusLog,
}

impl Messages {
    /// The messages of `log` from now on.
    pub fn new(log: LogBuffer) -> Self {
        Self {
            list: Vec::new(),
            seen: log.next_seq(),
            log,
            status_log: StatusLog::default(),
        }
    }

    /// The messages shown, oldest first.
    pub fn list(&self) -> &[Message] {
        &self.list
    }

    /// Removes message `k` (the operator dismissed it).
    pub fn dismiss(&mut self, k: usize) {
        if k < self.list.len() {
            self.list.remove(k);
        }
    }

    /// Reports a problem (`error`) or a note as an event, and shows it.
    pub fn note(&mut self, text: String, error: bool) {
        if error {
            tracing::error!("{text}");
        } else {
            tracing::info!("{text}");
        }
        self.read();
    }

    /// Passes the pipeline's new messages and problems in `status` on as
    /// events, and shows what reached the log.
    pub fn forward(&mut self, status: Option<&PipelineStatus>) {
        if let Some(st) = status {
            self.status_log.forward(st);
        }
        self.read();
    }

    /// Shows the events that reached the log since the last call.
    pub fn read(&mut self) {
        for e in self.log.read(&mut self.seen) {
            self.list.push(Message {
                error: e.is_problem(),
                text: e.message,
            });
        }
        let extra = self.list.len().saturating_sub(MESSAGES);
        self.list.drain(..extra);
    }
}
