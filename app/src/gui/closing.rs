//! When the window closes by itself: after `--quit-after`, or once the
//! screenshot `--screenshot` asks for is saved; and *File → Quit*.

use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

use anyhow::Result;

/// The window's own reasons to close.
#[derive(Debug)]
pub struct Closing {
    quit_at: Option<Instant>,
    want_close: bool,
    /// The screenshot to save and when.
    screenshot: Option<(PathBuf, Instant)>,
    /// The screenshot being saved.
    done: Option<Receiver<Result<()>>>,
}

impl Closing {
    /// Closes `quit_after` from now, or after saving a screenshot taken
    /// `screenshot`'s time from now.
    pub fn new(quit_after: Option<Duration>, screenshot: Option<(PathBuf, Duration)>) -> Self {
        let now = Instant::now();
        Self {
            quit_at: quit_after.map(|d| now + d),
            want_close: false,
            screenshot: screenshot.map(|(p, d)| (p, now + d)),
            done: None,
        }
    }

    /// Whether the window is to close.
    pub fn wants_close(&self) -> bool {
        self.want_close
    }

    /// Closes the window at its next frame.
    pub fn close(&mut self) {
        self.want_close = true;
    }

    /// Checks the time, takes the screenshot when it is due and follows
    /// its saving.
    pub fn poll(&mut self, ctx: &egui::Context) {
        if self.quit_at.is_some_and(|t| Instant::now() >= t) {
            self.want_close = true;
        }
        if let Some(rx) = &self.done {
            match rx.try_recv() {
                Ok(r) => {
                    self.done = None;
                    if let Err(e) = r {
                        tracing::error!("{e:#}");
                    }
                    self.want_close = true;
                }
                Err(mpsc::TryRecvError::Empty) => {
                    ctx.request_repaint_after(Duration::from_millis(50));
                }
                Err(mpsc::TryRecvError::Disconnected) => {
                    self.done = None;
                    self.want_close = true;
                }
            }
            return;
        }
        let due = self
            .screenshot
            .as_ref()
            .is_some_and(|(_, t)| Instant::now() >= *t);
        if !due {
            if self.screenshot.is_some() {
                ctx.request_repaint_after(Duration::from_millis(100));
            }
            return;
        }
        let Some((path, _)) = self.screenshot.take() else {
            return;
        };
        let (tx, rx) = mpsc::channel();
        let repaint = ctx.clone();
        ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(
            egui::ScreenshotCallback::new(move |img| {
                let [w, h] = img.size;
                let rgba: Vec<u8> = img.pixels.iter().flat_map(|c| c.to_array()).collect();
                let r = match (u32::try_from(w), u32::try_from(h)) {
                    (Ok(w), Ok(h)) => image::RgbaImage::from_raw(w, h, rgba)
                        .ok_or_else(|| anyhow::anyhow!("the screenshot has the wrong size"))
                        .and_then(|i| {
                            i.save(&path).map_err(|e| {
                                anyhow::anyhow!("writing the screenshot {}: {e}", path.display())
                            })
                        }),
                    _ => Err(anyhow::anyhow!("the screenshot is too large")),
                };
                let _ = tx.send(r);
                repaint.request_repaint();
            }),
        ));
        self.done = Some(rx);
    }
}
