//! `rigview eval import-brackets`: a bracket folder from a dataset laid out
//! as public bracket datasets are, one folder per camera and per exposure
//! time in it:
//!
//! ```text
//! SRC/<camera>/<exposure>/<image>.png
//! ```
//!
//! `<exposure>` is a number with its unit (`1ms`, `2000us`, `0.004s`; a
//! bare number takes `--unit`). The images of every exposure folder,
//! sorted by name, are the moments: the k-th image of each is moment k, at
//! `k / rate` seconds. The import writes `SRC/brackets.csv` (with the
//! layout and sensor comments given, over any manifest there) and copies
//! the rig beside it; the images stay where they are. The folder is then
//! opened as `--source brackets:SRC` opens it, so that anything wrong (a
//! camera folder the rig does not name, an image of another size) shows
//! at once, naming the manifest's line.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use super::manifest::{COLUMNS, MANIFEST, RIG};

/// What to import.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportSpec {
    /// The dataset's folder (the manifest is written into it).
    pub src: PathBuf,
    /// The rig's calibration, copied to `SRC/rig.yaml` (`None`: it must be
    /// there already).
    pub rig: Option<PathBuf>,
    /// The unit of exposure folders named by a bare number: `us`, `ms` or
    /// `s`.
    pub unit: Option<String>,
    /// Moments per second.
    pub rate_hz: f64,
    /// At most this many moments, from the first.
    pub moments: Option<usize>,
    /// `# key: value` lines for the manifest's head (`pattern: RGGB`,
    /// `bits: 12`, `response: linear`, …).
    pub comments: Vec<(String, String)>,
}

/// What an import wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// The manifest.
    pub manifest: PathBuf,
    /// The cameras, in the order found (by name).
    pub cameras: Vec<String>,
    /// Exposures per camera and moment.
    pub exposures: usize,
    /// Moments.
    pub moments: usize,
}

/// µs per unit.
fn unit_us(unit: &str) -> Option<f64> {
    match unit {
        "us" | "µs" => Some(1.0),
        "ms" => Some(1e3),
        "s" => Some(1e6),
        _ => None,
    }
}

/// The exposure (µs) a folder's `name` gives, with `unit` for a bare
/// number.
pub fn parse_exposure(name: &str, unit: Option<&str>) -> Result<f64> {
    let split = name
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == 'E' || c == '-'))
        .unwrap_or(name.len());
    let (number, suffix) = name.split_at(split);
    let value: f64 = number.parse().with_context(|| {
        format!("\"{name}\": expected an exposure time such as 1ms, 2000us or 0.004s")
    })?;
    let suffix = suffix.trim();
    let scale = if suffix.is_empty() {
        let unit = unit.with_context(|| {
            format!("\"{name}\": an exposure time without a unit; give --unit us, ms or s")
        })?;
        unit_us(unit).with_context(|| format!("--unit {unit}: expected us, ms or s"))?
    } else {
        unit_us(suffix)
            .with_context(|| format!("\"{name}\": unit \"{suffix}\" is none of us, ms and s"))?
    };
    let us = value * scale;
    if !(us.is_finite() && us > 0.0) {
        bail!("\"{name}\": expected a positive exposure time");
    }
    Ok(us)
}

/// The entries of `dir` that `keep` admits, sorted by name.
fn entries(dir: &Path, keep: fn(&Path) -> bool) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = entry
            .with_context(|| format!("reading {}", dir.display()))?
            .path();
        if keep(&path) {
            out.push(path);
        }
    }
    out.sort();
    Ok(out)
}

/// The sub-folders of `dir`, sorted by name.
fn folders(dir: &Path) -> Result<Vec<PathBuf>> {
    entries(dir, Path::is_dir)
}

/// The PNG images in `dir`, sorted by name.
fn images(dir: &Path) -> Result<Vec<PathBuf>> {
    entries(dir, |p| {
        p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"))
    })
}

/// A path's last component as text.
fn name_of(path: &Path) -> Result<String> {
    path.file_name()
        .and_then(|n| n.to_str())
        .map(str::to_string)
        .with_context(|| format!("{}: a name that is not UTF-8", path.display()))
}

/// Writes the manifest of `spec.src` (module documentation).
pub fn import(spec: &ImportSpec) -> Result<Imported> {
    if !(spec.rate_hz.is_finite() && spec.rate_hz > 0.0) {
        bail!("--rate {}: expected a positive rate in Hz", spec.rate_hz);
    }
    let src = &spec.src;
    // Per camera: per exposure (ascending), its images.
    let mut cameras = Vec::new();
    for cam_dir in folders(src)? {
        let camera = name_of(&cam_dir)?;
        let mut exposures = Vec::new();
        for exp_dir in folders(&cam_dir)? {
            let name = name_of(&exp_dir)?;
            let us = parse_exposure(&name, spec.unit.as_deref())
                .with_context(|| format!("the exposure folder {}", exp_dir.display()))?;
            exposures.push((us, images(&exp_dir)?, exp_dir));
        }
        if exposures.is_empty() {
            continue;
        }
        exposures.sort_by(|a, b| a.0.total_cmp(&b.0));
        cameras.push((camera, exposures));
    }
    let Some(first) = cameras.first() else {
        bail!(
            "{}: no camera folder with exposure folders in it (expected SRC/<camera>/<exposure>/<image>.png)",
            src.display()
        );
    };
    let per_camera = first.1.len();
    let mut moments = first.1[0].1.len();
    for (camera, exposures) in &cameras {
        if exposures.len() != per_camera {
            bail!(
                "camera {camera}: {} exposure folders, camera {}: {per_camera}; expected the same exposures for every camera",
                exposures.len(),
                first.0
            );
        }
        for (_, files, dir) in exposures {
            if files.len() != moments {
                bail!(
                    "{}: {} images, {}: {moments}; expected one image per moment in every exposure folder",
                    dir.display(),
                    files.len(),
                    first.1[0].2.display()
                );
            }
        }
    }
    if let Some(m) = spec.moments {
        moments = moments.min(m);
    }
    if moments == 0 {
        bail!("{}: no images in the exposure folders", src.display());
    }

    let mut text = String::new();
    for (key, value) in &spec.comments {
        let _ = writeln!(text, "# {key}: {value}");
    }
    let _ = writeln!(text, "{}", COLUMNS.join(","));
    for k in 0..moments {
        let time = k as f64 / spec.rate_hz;
        for (camera, exposures) in &cameras {
            for (us, files, _) in exposures {
                let rel = files[k].strip_prefix(src).with_context(|| {
                    format!("{} lies outside {}", files[k].display(), src.display())
                })?;
                let rel = rel
                    .to_str()
                    .with_context(|| format!("{}: a path that is not UTF-8", rel.display()))?;
                if rel.contains(',') {
                    bail!("{rel}: a comma in a file name cannot go into the manifest");
                }
                let _ = writeln!(text, "{camera},{k},{time:.6},{us:.3},0,{rel}");
            }
        }
    }
    if let Some(rig) = &spec.rig {
        let to = src.join(RIG);
        std::fs::copy(rig, &to)
            .with_context(|| format!("copying {} to {}", rig.display(), to.display()))?;
    }
    let manifest = src.join(MANIFEST);
    std::fs::write(&manifest, text).with_context(|| format!("writing {}", manifest.display()))?;
    let names: Vec<String> = cameras.iter().map(|c| c.0.clone()).collect();
    let options =
        super::BracketOptions::new(crate::session::BRACKETS_START, super::BracketMode::Nearest);
    super::open_with_rig(src, None, &options)
        .with_context(|| format!("reading back {}", manifest.display()))?;
    Ok(Imported {
        manifest,
        cameras: names,
        exposures: per_camera,
        moments,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::float_cmp)] // exact products of small numbers
    fn exposure_folder_names_with_and_without_units() {
        assert_eq!(parse_exposure("1ms", None).unwrap(), 1000.0);
        assert_eq!(parse_exposure("2000us", None).unwrap(), 2000.0);
        assert_eq!(parse_exposure("0.004s", None).unwrap(), 4000.0);
        assert_eq!(parse_exposure("16", Some("ms")).unwrap(), 16000.0);
        let e = parse_exposure("16", None).unwrap_err().to_string();
        assert!(e.contains("--unit"), "{e}");
        let e = parse_exposure("16min", None).unwrap_err().to_string();
        assert!(e.contains("\"min\""), "{e}");
        let e = parse_exposure("dark", None).unwrap_err().to_string();
        assert!(e.contains("\"dark\""), "{e}");
        assert!(parse_exposure("0ms", None).is_err());
    }
}
