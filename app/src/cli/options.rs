//! The options several commands share: the window's (`--settings`,
//! `--quit-after`, `--screenshot`), the processing overrides
//! (`--strategy`, `--law`, `--simulation`, `--meter`, `--probe`,
//! `--blend`, `--view` and the panorama's), how a recording is written,
//! and the parsers of values several commands take.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;
use rigview_core::bowl::Viewpoint;
use rigview_core::exposure::{LawKind, PixelFormat, ProbeParams, Simulation, ToneCurve};
use rigview_core::pipeline::{MeterRoi, PipelineOptions, ProcessingSettings, Strategy, ViewKind};
use rigview_core::surround::BlendMode;
use rigview_record::Compression;

use crate::gui::{self, AppOptions};
use crate::logging::LogBuffer;
use crate::session::{RecordSpec, SourceSpec};
use crate::settings::{Settings, SettingsStore, ViewMode};

/// Options of the window and of `rigview run`.
#[derive(Clone, Debug, Default, Args)]
pub struct ViewArgs {
    /// The settings file [default: ~/.config/rigview/settings.yaml].
    #[arg(long, value_name = "FILE", global = true)]
    pub settings: Option<PathBuf>,
    /// Close the window after this many seconds (for scripted runs).
    #[arg(long, value_name = "S", global = true)]
    pub quit_after: Option<f64>,
    /// Save a screenshot of the window to FILE (PNG) after
    /// `--screenshot-after` seconds, then close it.
    #[arg(long, value_name = "FILE", global = true)]
    pub screenshot: Option<PathBuf>,
    /// Seconds before the screenshot.
    #[arg(long, value_name = "S", default_value_t = 8.0, global = true)]
    pub screenshot_after: f64,
    /// The window's size in points, WIDTHxHEIGHT [default: 1600x1000].
    #[arg(long, value_name = "WxH", global = true)]
    pub window_size: Option<String>,
}

impl ViewArgs {
    /// The saved settings (`--settings FILE` or the default file), with
    /// `overrides` applied; a settings file that cannot be read is reported
    /// on stderr and the defaults are used.
    pub fn settings(&self, overrides: &ProcessingArgs) -> Settings {
        let mut store = SettingsStore::new(self.settings.clone());
        let (mut settings, err) = store.load();
        if let Some(e) = err {
            tracing::warn!("{e:#}");
        }
        overrides.apply(&mut settings.processing);
        settings
    }

    /// `--screenshot` and `--screenshot-after`.
    pub fn screenshot(&self) -> Result<Option<(PathBuf, Duration)>> {
        let Some(p) = &self.screenshot else {
            return Ok(None);
        };
        let after = Duration::try_from_secs_f64(self.screenshot_after)
            .context("--screenshot-after: expected a number of seconds ≥ 0")?;
        Ok(Some((p.clone(), after)))
    }

    /// `--window-size` as width and height, points.
    pub fn window_size(&self) -> Result<Option<[f32; 2]>> {
        let Some(text) = &self.window_size else {
            return Ok(None);
        };
        let parsed = text.split_once(['x', '×']).and_then(|(w, h)| {
            let (w, h) = (w.trim().parse::<f32>().ok()?, h.trim().parse::<f32>().ok()?);
            (w.is_finite()
                && h.is_finite()
                && (320.0..=16384.0).contains(&w)
                && (240.0..=16384.0).contains(&h))
            .then_some([w, h])
        });
        match parsed {
            Some(size) => Ok(Some(size)),
            None => anyhow::bail!(
                "--window-size: expected WIDTHxHEIGHT in points (320x240 to 16384x16384), e.g. 1600x1000; got {text:?}"
            ),
        }
    }

    /// `--quit-after` as a duration.
    pub fn quit_after(&self) -> Result<Option<Duration>> {
        self.quit_after
            .map(Duration::try_from_secs_f64)
            .transpose()
            .context("--quit-after: expected a number of seconds ≥ 0")
    }

    /// The window on `source`, with `overrides` saved into the settings it
    /// opens with.
    pub fn window(
        &self,
        overrides: &ProcessingArgs,
        source: SourceSpec,
        record: Option<RecordSpec>,
        serve: Option<crate::serve::ServeOptions>,
    ) -> Result<()> {
        let mut store = SettingsStore::new(self.settings.clone());
        let (mut settings, err) = store.load();
        if let Some(e) = err {
            tracing::warn!("{e:#}");
        } else {
            overrides.apply(&mut settings.processing);
            if let Some(v) = overrides.view {
                settings.window.view = match v {
                    ViewKind::Surround => ViewMode::Surround,
                    ViewKind::Panorama => ViewMode::Panorama,
                    ViewKind::Bowl => ViewMode::Bowl,
                };
            }
            store.save(&settings)?;
        }
        gui::run(AppOptions {
            source,
            settings: self.settings.clone(),
            quit_after: self.quit_after()?,
            screenshot: self.screenshot()?,
            window_size: self.window_size()?,
            serve,
            pipeline: PipelineOptions::default(),
            log: LogBuffer::global().clone(),
            record,
        })
    }
}

/// The live remote view (`--serve`).
#[derive(Clone, Debug, Default, Args)]
pub struct ServeArgs {
    /// Serve a live remote view for Foxglove (WebSocket) on [ADDR:]PORT:
    /// a port alone, or `--serve` with nothing, listens on loopback
    /// (127.0.0.1:8765 by default); another address must be given
    /// explicitly, and the stream is unauthenticated (docs/remote-view.md).
    #[arg(long, value_name = "[ADDR:]PORT", num_args = 0..=1, default_missing_value = crate::serve::DEFAULT_ADDR)]
    pub serve: Option<String>,
    /// Pictures a second the remote view sends, at most.
    #[arg(long, value_name = "HZ", default_value_t = 10.0)]
    pub serve_rate: f64,
    /// The remote view's camera pictures at 1/N of the cameras' size.
    #[arg(long, value_name = "N", default_value_t = 2)]
    pub serve_shrink: usize,
    /// If the remote view's address cannot be bound, go on without it
    /// (otherwise rigview stops before starting).
    #[arg(long)]
    pub serve_optional: bool,
}

impl ServeArgs {
    /// The remote view's options (`None`: not asked for, or not bound
    /// and `--serve-optional`): the address is checked here, before the
    /// session starts.
    pub fn options(&self) -> Result<Option<crate::serve::ServeOptions>> {
        let Some(text) = &self.serve else {
            return Ok(None);
        };
        let addr = crate::serve::parse_addr(text).map_err(anyhow::Error::msg)?;
        if !(self.serve_rate.is_finite() && (0.1..=100.0).contains(&self.serve_rate)) {
            anyhow::bail!(
                "--serve-rate: expected 0.1 to 100 pictures a second; got {}",
                self.serve_rate
            );
        }
        if !(1..=16).contains(&self.serve_shrink) {
            anyhow::bail!(
                "--serve-shrink: expected 1 to 16; got {}",
                self.serve_shrink
            );
        }
        if !addr.ip().is_loopback() {
            tracing::warn!(
                "the remote view listens on {addr}, beyond this machine: anyone who reaches it sees the cameras (the stream is unauthenticated)"
            );
        }
        if let Err(e) = std::net::TcpListener::bind(addr) {
            let e = anyhow::anyhow!("--serve {addr}: cannot listen there: {e}");
            if self.serve_optional {
                tracing::warn!("{e:#}; going on without the remote view (--serve-optional)");
                return Ok(None);
            }
            return Err(e.context("(add --serve-optional to go on without the remote view)"));
        }
        Ok(Some(crate::serve::ServeOptions {
            addr,
            rate_hz: self.serve_rate,
            shrink: self.serve_shrink,
            ..crate::serve::ServeOptions::default()
        }))
    }
}

/// Options of the control loop, for every command that runs it: they
/// override the saved settings (`rigview demo`: the built-in defaults).
#[derive(Clone, Debug, Default, Args)]
pub struct ControlArgs {
    /// How exposure is decided.
    #[arg(long, value_enum)]
    pub strategy: Option<Strategy>,
    /// The update law.
    #[arg(long, value_enum)]
    pub law: Option<LawKind>,
    /// The estimator's exposure simulation.
    #[arg(long, value_enum)]
    pub simulation: Option<Simulation>,
    /// Which pixels are metered.
    #[arg(long, value_enum, value_name = "ROI")]
    pub meter: Option<MeterRoi>,
    /// Darker probes of a camera under its own law (`off` for measuring
    /// the law alone).
    #[arg(long, value_enum, value_name = "ON|OFF")]
    pub probe: Option<Switch>,
    /// The cameras' tone curve, which scale-and-clip simulates exposure
    /// under: a display gamma (2.2 for sRGB-like frames), or `off` for
    /// linear frames.
    #[arg(long, value_name = "GAMMA|off", value_parser = tone_curve)]
    pub tone_curve: Option<ToneArg>,
}

/// `--tone-curve`: a power curve, or none.
#[derive(Clone, Debug, PartialEq)]
pub struct ToneArg(pub Option<ToneCurve>);

fn tone_curve(s: &str) -> std::result::Result<ToneArg, String> {
    if s.trim().eq_ignore_ascii_case("off") {
        return Ok(ToneArg(None));
    }
    let curve = s
        .trim()
        .parse::<f64>()
        .ok()
        .map(ToneCurve::Power)
        .filter(|c| c.validate().is_ok());
    match curve {
        Some(c) => Ok(ToneArg(Some(c))),
        None => Err(format!(
            "{s:?}: expected a display gamma in (0, 10] (2.2 for sRGB-like frames) or off"
        )),
    }
}

/// Processing options that override the saved settings, for every command
/// that runs the processor and composes a view: the control loop's, and
/// the view's blending.
#[derive(Clone, Debug, Default, Args)]
pub struct ProcessingArgs {
    /// The control loop's options.
    #[command(flatten)]
    pub control: ControlArgs,
    /// How the overlaps of the view are blended (overrides the saved
    /// choice).
    #[arg(long, value_enum)]
    pub blend: Option<BlendMode>,
    /// The view composed (and what is metered, and where the overlap
    /// ratios come from): the bird's-eye surround view, the cylindrical
    /// panorama with ratios from matched features, or the 3-D bowl around
    /// the vehicle (metered and balanced as the bird's-eye view).
    #[arg(long, value_enum)]
    pub view: Option<ViewKind>,
    /// Where the bowl is seen from: top, rear, front, behind-left,
    /// behind-right, left or right.
    #[arg(long, value_name = "NAME", value_parser = viewpoint)]
    pub viewpoint: Option<Viewpoint>,
    /// A vehicle model for the bowl instead of the built-in one: glTF 2.0
    /// (`.gltf` with its `.bin`, or `.glb`; front along +z) or Wavefront
    /// OBJ (front along −z); y up, scaled onto the vehicle's box.
    #[arg(long, value_name = "FILE")]
    pub vehicle_model: Option<std::path::PathBuf>,
    /// The panorama's radius, metres: what stands this far from the rig's
    /// centre lines up across the seams; nearer things show parallax.
    #[arg(long, value_name = "M")]
    pub radius_m: Option<f64>,
    /// Match the panorama's features on every N-th set (in the background).
    #[arg(long, value_name = "N")]
    pub match_every: Option<u64>,
    /// Refine the panorama's rotations in the background every N sets (0:
    /// never).
    #[arg(long, value_name = "N")]
    pub refine_every: Option<u64>,
}

/// A setting switched on or off on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Switch {
    /// On.
    On,
    /// Off.
    Off,
}

impl ControlArgs {
    /// Applies the options given to `p`.
    pub fn apply(&self, p: &mut ProcessingSettings) {
        if let Some(s) = self.strategy {
            p.strategy = s;
        }
        if let Some(l) = self.law {
            p.controller.law.kind = l;
        }
        if let Some(s) = self.simulation {
            p.controller.estimator.simulation = s;
        }
        if let Some(m) = self.meter {
            p.roi = m;
        }
        if let Some(ToneArg(c)) = &self.tone_curve {
            p.controller.estimator.tone_curve.clone_from(c);
        }
        match self.probe {
            Some(Switch::Off) => p.controller.probe = None,
            Some(Switch::On) => {
                p.controller.probe.get_or_insert_with(ProbeParams::default);
            }
            None => {}
        }
    }
}

impl ProcessingArgs {
    /// Applies the options given to `p`.
    pub fn apply(&self, p: &mut ProcessingSettings) {
        self.control.apply(p);
        if let Some(b) = self.blend {
            p.blend = b;
        }
        if let Some(v) = self.view {
            p.view = v;
        }
        if let Some(v) = self.viewpoint {
            p.bowl.viewpoint = v;
        }
        if let Some(m) = &self.vehicle_model {
            p.bowl.spec.vehicle_model = Some(m.clone());
        }
        if let Some(r) = self.radius_m {
            p.panorama.radius_m = r;
        }
        if let Some(n) = self.match_every {
            p.panorama.match_every = n;
        }
        if let Some(n) = self.refine_every {
            p.panorama.refine_every = n;
        }
    }
}

/// A viewpoint of the bowl by its preset's name.
fn viewpoint(name: &str) -> std::result::Result<Viewpoint, String> {
    Viewpoint::preset(name).map_err(|e| e.to_string())
}

/// A number of seconds ≥ 0 given as `--what`.
pub(crate) fn seconds(what: &str, s: f64) -> Result<Duration> {
    Duration::try_from_secs_f64(s)
        .with_context(|| format!("--{what} {s}: expected a number of seconds ≥ 0"))
}

/// How a recording is written.
#[derive(Clone, Debug, Default, Args)]
pub struct RecordingArgs {
    /// Chunk compression of the recording (none by default: rig frames
    /// shrink by a sixth at most).
    #[arg(long, value_name = "none|lz4|zstd", default_value = "none")]
    pub compression: Compression,
    /// Free space to leave on the recording's disk, GiB.
    #[arg(long, value_name = "GIB", default_value_t = 2.0)]
    pub reserve_gib: f64,
}

impl RecordingArgs {
    /// The recording into `file`.
    pub fn spec(&self, file: PathBuf) -> RecordSpec {
        RecordSpec {
            file,
            compression: self.compression,
            reserve_bytes: (self.reserve_gib.max(0.0) * f64::from(1u32 << 30)) as u64,
        }
    }
}

/// A pixel format by its GenICam name (any case), for `--pixel-format`.
pub fn parse_pixel_format(s: &str) -> std::result::Result<PixelFormat, String> {
    PixelFormat::ALL
        .into_iter()
        .find(|f| f.genicam_name().eq_ignore_ascii_case(s))
        .ok_or_else(|| {
            let names: Vec<_> = PixelFormat::ALL.iter().map(|f| f.genicam_name()).collect();
            format!("unknown pixel format \"{s}\" (known: {})", names.join(", "))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tone_curve_is_a_gamma_or_off() {
        assert_eq!(tone_curve("2.2"), Ok(ToneArg(Some(ToneCurve::Power(2.2)))));
        assert_eq!(tone_curve("OFF"), Ok(ToneArg(None)));
        for bad in ["0", "-1", "gamma", "11", "NaN"] {
            let e = tone_curve(bad).unwrap_err();
            assert!(e.contains(bad) && e.contains("display gamma"), "{e}");
        }
        let mut p = ProcessingSettings::default();
        let args = |c| ControlArgs {
            tone_curve: Some(ToneArg(c)),
            ..ControlArgs::default()
        };
        args(Some(ToneCurve::Power(1.8))).apply(&mut p);
        assert_eq!(
            p.controller.estimator.tone_curve,
            Some(ToneCurve::Power(1.8))
        );
        args(None).apply(&mut p);
        assert_eq!(p.controller.estimator.tone_curve, None);
        // Left out, the saved curve stays.
        p.controller.estimator.tone_curve = Some(ToneCurve::Power(2.4));
        ControlArgs::default().apply(&mut p);
        assert_eq!(
            p.controller.estimator.tone_curve,
            Some(ToneCurve::Power(2.4))
        );
    }

    #[test]
    fn the_window_size_is_read_or_refused_with_what_was_expected() {
        let args = |s: &str| ViewArgs {
            window_size: Some(s.into()),
            ..ViewArgs::default()
        };
        assert_eq!(
            args("2017x1277").window_size().unwrap(),
            Some([2017.0, 1277.0])
        );
        assert_eq!(
            args("1600×1000").window_size().unwrap(),
            Some([1600.0, 1000.0])
        );
        assert_eq!(ViewArgs::default().window_size().unwrap(), None);
        for bad in ["12by3", "100x100", "1600x", "nanxnan", "1e9x800"] {
            let e = args(bad).window_size().unwrap_err().to_string();
            assert!(
                e.contains("--window-size") && e.contains("WIDTHxHEIGHT") && e.contains(bad),
                "{e}"
            );
        }
    }
}
