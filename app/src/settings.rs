//! The settings that persist between runs: the processing settings
//! (strategy, law, parameters, metering, blending) and the window's
//! choices, as YAML in the user's configuration folder
//! (`~/.config/rigview/settings.yaml` on Linux) or a file named with
//! `--settings`.
//!
//! A settings file that cannot be read is reported (file, field, what was
//! expected) and rigview starts from the defaults. The broken file is not
//! overwritten: before the first save it is moved aside to
//! `settings.yaml.broken`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rigview_core::pipeline::ProcessingSettings;
use serde::{Deserialize, Serialize};

/// The file's format tag.
pub const FORMAT: &str = "rigview-settings";
/// The file's version.
pub const VERSION: u32 = 1;

/// What the big view shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ViewMode {
    /// The bird's-eye surround view.
    #[default]
    Surround,
    /// The cylindrical panorama.
    Panorama,
    /// The 3-D bowl around the vehicle.
    Bowl,
}

/// What draws the bowl in the window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BowlRenderer {
    /// The GPU where the window's OpenGL is a GPU's; the CPU where it is a
    /// software renderer (Mesa's llvmpipe draws the bowl more slowly than
    /// the pipeline composes it).
    #[default]
    Auto,
    /// The GPU (or the GL's software renderer): a new viewpoint at once.
    Gpu,
    /// The pipeline, on the CPU: a new viewpoint is rebuilt in the
    /// background.
    Cpu,
}

impl BowlRenderer {
    /// Every choice, for the window's menu.
    pub const ALL: [Self; 3] = [Self::Auto, Self::Gpu, Self::Cpu];

    /// Its name in the window.
    pub fn label(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Gpu => "GPU",
            Self::Cpu => "CPU",
        }
    }
}

impl ViewMode {
    /// The view the pipeline composes for this choice.
    pub fn kind(self) -> rigview_core::pipeline::ViewKind {
        match self {
            Self::Surround => rigview_core::pipeline::ViewKind::Surround,
            Self::Panorama => rigview_core::pipeline::ViewKind::Panorama,
            Self::Bowl => rigview_core::pipeline::ViewKind::Bowl,
        }
    }
}

/// The window's choices.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WindowSettings {
    /// What the big view shows.
    pub view: ViewMode,
    /// Draw the metering ROI over the thumbnails.
    pub show_roi: bool,
    /// Draw the overlap patches over the thumbnails.
    pub show_patches: bool,
    /// Draw the panorama's matches (inliers green, outliers red) and its
    /// overlap bands over it.
    pub show_matches: bool,
    /// Seconds of history in the scrolling plots.
    pub plot_seconds: f64,
    /// The camera whose M(γ) curve is plotted.
    pub selected_camera: usize,
    /// Calibration files opened recently, newest first.
    pub recent: Vec<PathBuf>,
    /// The bowl view turns to the rear view while the vehicle reverses.
    pub rear_when_reversing: bool,
    /// What draws the bowl in the window.
    pub bowl_renderer: BowlRenderer,
}

impl Default for WindowSettings {
    fn default() -> Self {
        Self {
            view: ViewMode::Surround,
            show_roi: true,
            show_patches: true,
            show_matches: true,
            plot_seconds: 20.0,
            selected_camera: 0,
            recent: Vec::new(),
            rear_when_reversing: true,
            bowl_renderer: BowlRenderer::Auto,
        }
    }
}

/// Everything that persists.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Settings {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
    /// What the processing does.
    pub processing: ProcessingSettings,
    /// The window's choices.
    pub window: WindowSettings,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            format: FORMAT.into(),
            version: VERSION,
            processing: ProcessingSettings::default(),
            window: WindowSettings::default(),
        }
    }
}

impl Settings {
    /// Parses a settings file's text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self> {
        let s: Settings = serde_norway::from_str(text).with_context(|| {
            format!("settings file {file}: not valid settings (the field and what was expected are named below)")
        })?;
        if s.format != FORMAT {
            anyhow::bail!(
                "settings file {file}: field `format` is \"{}\": expected \"{FORMAT}\"",
                s.format
            );
        }
        if s.version != VERSION {
            anyhow::bail!(
                "settings file {file}: field `version` is {}: expected {VERSION}",
                s.version
            );
        }
        s.processing
            .validate()
            .with_context(|| format!("settings file {file}: field `processing`"))?;
        if !(s.window.plot_seconds.is_finite() && (1.0..=600.0).contains(&s.window.plot_seconds)) {
            anyhow::bail!(
                "settings file {file}: field `window.plot_seconds` is {}: expected 1 to 600 seconds",
                s.window.plot_seconds
            );
        }
        Ok(s)
    }

    /// The settings as YAML.
    pub fn to_yaml(&self) -> Result<String> {
        serde_norway::to_string(self).context("writing the settings as YAML")
    }
}

/// Where the settings live and whether they may be overwritten.
#[derive(Debug)]
pub struct SettingsStore {
    path: Option<PathBuf>,
    /// The file was there but broken: move it aside before saving.
    broken: bool,
}

impl SettingsStore {
    /// The store at `path`, or the user's configuration folder; `None`
    /// there when the system has no home folder (settings then do not
    /// persist).
    pub fn new(path: Option<PathBuf>) -> Self {
        let path = path.or_else(|| {
            directories::ProjectDirs::from("", "", "rigview")
                .map(|d| d.config_dir().join("settings.yaml"))
        });
        Self {
            path,
            broken: false,
        }
    }

    /// The file.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// Loads the settings: the defaults when there is no file yet, and the
    /// defaults with the error when the file is broken.
    pub fn load(&mut self) -> (Settings, Option<anyhow::Error>) {
        let Some(path) = &self.path else {
            return (Settings::default(), None);
        };
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return (Settings::default(), None)
            }
            Err(e) => {
                self.broken = true;
                return (
                    Settings::default(),
                    Some(anyhow::anyhow!(
                        "settings file {}: cannot read it: {e}",
                        path.display()
                    )),
                );
            }
        };
        match Settings::parse(&text, &path.display().to_string()) {
            Ok(s) => (s, None),
            Err(e) => {
                self.broken = true;
                (
                    Settings::default(),
                    Some(e.context("rigview starts from the default settings; the file is kept")),
                )
            }
        }
    }

    /// Saves the settings (atomically: a temporary file, then a rename). A
    /// broken file found at load is first moved aside.
    pub fn save(&mut self, settings: &Settings) -> Result<()> {
        let Some(path) = &self.path else {
            return Ok(());
        };
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating the settings folder {}", dir.display()))?;
        }
        if self.broken {
            let aside = path.with_extension("yaml.broken");
            std::fs::rename(path, &aside).with_context(|| {
                format!(
                    "moving the broken settings file {} aside to {}",
                    path.display(),
                    aside.display()
                )
            })?;
            self.broken = false;
        }
        let tmp = path.with_extension("yaml.tmp");
        std::fs::write(&tmp, settings.to_yaml()?)
            .with_context(|| format!("writing the settings file {}", tmp.display()))?;
        std::fs::rename(&tmp, path)
            .with_context(|| format!("writing the settings file {}", path.display()))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigview_core::exposure::ToneCurve;
    use rigview_core::pipeline::Strategy;

    #[test]
    fn settings_round_trip_through_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("settings.yaml");
        let mut store = SettingsStore::new(Some(path.clone()));
        let mut s = Settings::default();
        s.processing.strategy = Strategy::Single;
        s.processing.controller.law.kp = 0.4;
        s.window.plot_seconds = 42.0;
        store.save(&s).unwrap();
        let (back, err) = SettingsStore::new(Some(path)).load();
        assert!(err.is_none(), "{err:?}");
        assert_eq!(back, s);
    }

    #[test]
    fn a_broken_file_names_the_field_and_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("settings.yaml");
        let mut s = Settings::default().to_yaml().unwrap();
        s = s.replace("kp: 1.0", "kp: fast");
        std::fs::write(&path, &s).unwrap();
        let mut store = SettingsStore::new(Some(path.clone()));
        let (loaded, err) = store.load();
        assert_eq!(loaded, Settings::default());
        let msg = format!("{:#}", err.unwrap());
        assert!(msg.contains("settings.yaml"), "{msg}");
        assert!(msg.contains("kp"), "{msg}");
        store.save(&Settings::default()).unwrap();
        let aside = std::fs::read_to_string(path.with_extension("yaml.broken")).unwrap();
        assert_eq!(aside, s, "the broken file was not kept as it was");
    }

    #[test]
    fn an_out_of_range_parameter_is_refused_with_its_name() {
        let mut s = Settings::default();
        s.processing.controller.estimator.metric.delta = -1.0;
        let text = s.to_yaml().unwrap();
        let msg = format!("{:#}", Settings::parse(&text, "s.yaml").unwrap_err());
        assert!(msg.contains("s.yaml") && msg.contains("delta"), "{msg}");
    }

    #[test]
    fn a_tone_curve_is_read_from_the_settings_and_checked() {
        let text = Settings::default().to_yaml().unwrap();
        assert!(!text.contains("tone_curve"), "written only when set");
        let at = "    estimator:\n";
        assert!(text.contains(at), "{text}");
        let with = |curve: &str| text.replacen(at, &format!("{at}      tone_curve: {curve}\n"), 1);
        let power = Settings::parse(&with("2.2"), "gamma.yaml").unwrap();
        assert_eq!(
            power.processing.controller.estimator.tone_curve,
            Some(ToneCurve::Power(2.2))
        );
        let table = Settings::parse(&with("[0.0, 0.2, 1.0]"), "table.yaml").unwrap();
        assert_eq!(
            table.processing.controller.estimator.tone_curve,
            Some(ToneCurve::Table(vec![0.0, 0.2, 1.0]))
        );
        // Written back as read.
        let again = Settings::parse(&table.to_yaml().unwrap(), "again.yaml").unwrap();
        assert_eq!(again, table);
        for bad in ["[0.0, 0.7, 0.5, 1.0]", "0", "[0.0, 0.5]"] {
            let msg = format!("{:#}", Settings::parse(&with(bad), "bad.yaml").unwrap_err());
            assert!(
                msg.contains("bad.yaml") && msg.contains("tone_curve"),
                "{bad}: {msg}"
            );
        }
    }

    #[test]
    fn a_file_from_before_probing_probes_and_null_turns_it_off() {
        let text = Settings::default().to_yaml().unwrap();
        let block: String = text
            .lines()
            .skip_while(|l| *l != "    probe:")
            .take_while(|l| *l == "    probe:" || l.starts_with("      "))
            .map(|l| format!("{l}\n"))
            .collect();
        assert!(block.contains("step_ev:"), "{text}");
        let before = text.replacen(&block, "", 1);
        let old = Settings::parse(&before, "old.yaml").unwrap();
        assert_eq!(old, Settings::default(), "a file without `probe` probes");
        // Nor did the damping have `recover_ev`.
        assert!(before.contains("recover_ev: 0.5\n"), "{before}");
        let older: String = before
            .lines()
            .filter(|l| !l.trim_start().starts_with("recover_ev:"))
            .map(|l| format!("{l}\n"))
            .collect();
        let older = Settings::parse(&older, "older.yaml").unwrap();
        assert_eq!(older, Settings::default(), "a damping without `recover_ev`");
        let off = Settings::parse(
            &before.replacen("  controller:\n", "  controller:\n    probe: null\n", 1),
            "off.yaml",
        )
        .unwrap();
        assert_eq!(off.processing.controller.probe, None);
        let bad = text.replacen("      step_ev: 0.9", "      step_ev: 9", 1);
        let msg = format!("{:#}", Settings::parse(&bad, "bad.yaml").unwrap_err());
        assert!(
            msg.contains("bad.yaml") && msg.contains("controller.probe.step_ev"),
            "{msg}"
        );
        let typo = text.replacen("      step_ev:", "      stepev:", 1);
        let msg = format!("{:#}", Settings::parse(&typo, "typo.yaml").unwrap_err());
        assert!(msg.contains("typo.yaml") && msg.contains("stepev"), "{msg}");
    }
}
