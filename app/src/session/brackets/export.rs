//! Writing bracket folders: [`BracketWriter`] (one whole moment at a
//! time) and the export from the simulated rig.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use rigview_core::exposure::{ExposureSetting, PixelFormat};

use super::{COLUMNS, MANIFEST, OPTIONAL, RIG};

/// What [`export`] writes.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportSpec {
    /// Moments (sets of the simulation, from its start).
    pub frames: usize,
    /// Exposure levels (µs at 0 dB) of every bracket.
    pub levels: Vec<f64>,
}

/// `--range-ev LO:HI`: two levels in log2 µs, `0 ≤ LO < HI ≤ 30`.
pub fn parse_range_ev(text: &str) -> Result<(f64, f64)> {
    let parse = |s: &str| s.trim().parse::<f64>().ok().filter(|v| v.is_finite());
    match text.split_once(':').map(|(a, b)| (parse(a), parse(b))) {
        Some((Some(lo), Some(hi))) if lo < hi && (0.0..=30.0).contains(&lo) && hi <= 30.0 => {
            Ok((lo, hi))
        }
        _ => bail!("--range-ev {text}: expected LO:HI in log2 µs, 0 ≤ LO < HI ≤ 30 (e.g. 8:13)"),
    }
}

/// The exposure levels of `n` brackets evenly spaced in log2 from
/// `lo_ev` to `hi_ev` (log2 µs).
pub fn levels(lo_ev: f64, hi_ev: f64, n: usize) -> Vec<f64> {
    let n = n.max(1);
    (0..n)
        .map(|k| {
            let t = if n == 1 {
                0.0
            } else {
                k as f64 / (n - 1) as f64
            };
            (lo_ev + (hi_ev - lo_ev) * t).exp2()
        })
        .collect()
}

/// Writes a bracket sequence into a folder, one whole moment at a time: a
/// moment's images and manifest lines are written only once every camera's
/// bracket is complete, and the manifest is flushed after each, so that a
/// sequence cut short (a camera lost, the disk full, the program stopped)
/// keeps every moment written before, readable as it is.
#[derive(Debug)]
pub struct BracketWriter {
    dir: PathBuf,
    manifest: std::fs::File,
    cameras: Vec<String>,
    moments: usize,
}

/// One image of a moment for [`BracketWriter::write_moment`].
#[derive(Clone, Copy, Debug)]
pub struct BracketFrame<'a> {
    /// The camera's index in the rig.
    pub camera: usize,
    /// What it was taken with (as the camera reported it).
    pub setting: ExposureSetting,
    /// Its pixels.
    pub format: PixelFormat,
    /// Its size.
    pub width: usize,
    /// Its size.
    pub height: usize,
    /// Its pixels, `format`'s layout.
    pub data: &'a [u8],
}

impl BracketWriter {
    /// Creates `dir` with the rig's calibration (when known), a folder per
    /// camera and the manifest's header; `title` is its first comment line.
    pub fn create(
        dir: &Path,
        rig: Option<&rigview_calib::Rig>,
        cameras: &[String],
        title: &str,
    ) -> Result<Self> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let path = dir.join(MANIFEST);
        if path.exists() {
            bail!(
                "{} exists already: write brackets into a new folder",
                path.display()
            );
        }
        if let Some(rig) = rig {
            rigview_calib::formats::save(rig, &dir.join(RIG), None)
                .with_context(|| format!("writing {}", dir.join(RIG).display()))?;
        }
        for name in cameras {
            std::fs::create_dir_all(dir.join(name))
                .with_context(|| format!("creating {}", dir.join(name).display()))?;
        }
        let mut manifest =
            std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        use std::io::Write;
        // Raw frames (the simulated rig's, GenICam cameras' Mono and Bayer
        // formats) are linear.
        write!(
            manifest,
            "# {title}\n# response: linear\n{},{}\n",
            COLUMNS.join(","),
            OPTIONAL.join(",")
        )
        .and_then(|()| manifest.flush())
        .with_context(|| format!("writing {}", path.display()))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            manifest,
            cameras: cameras.to_vec(),
            moments: 0,
        })
    }

    /// Moments written so far.
    pub fn moments(&self) -> usize {
        self.moments
    }

    /// Writes the next moment, taken `time_s` after the first: its images
    /// (8-bit formats as 8-bit grey PNG, the wider ones as 16-bit grey with
    /// their values unchanged; Bayer mosaics as they are), then their lines
    /// of the manifest with each image's pattern and bits.
    pub fn write_moment(&mut self, time_s: f64, frames: &[BracketFrame<'_>]) -> Result<()> {
        use std::io::Write;
        let n = self.moments;
        let mut lines = String::new();
        let mut per_camera = vec![0usize; self.cameras.len()];
        for f in frames {
            let name = self.cameras.get(f.camera).with_context(|| {
                format!(
                    "a frame of camera {} in a rig of {} cameras",
                    f.camera,
                    self.cameras.len()
                )
            })?;
            let k = per_camera[f.camera];
            per_camera[f.camera] += 1;
            let file = format!("{name}/{n:06}_{k:02}.png");
            let path = self.dir.join(&file);
            write_png(&path, f)
                .with_context(|| format!("writing {} (camera \"{name}\")", path.display()))?;
            lines += &format!(
                "{name},{n},{time_s:.6},{:.3},{:.3},{file},{},{}\n",
                f.setting.shutter_us,
                f.setting.gain_db,
                f.format.bayer_pattern().unwrap_or("mono"),
                f.format.bits()
            );
        }
        let path = self.dir.join(MANIFEST);
        self.manifest
            .write_all(lines.as_bytes())
            .and_then(|()| self.manifest.flush())
            .with_context(|| format!("writing {}", path.display()))?;
        self.moments += 1;
        Ok(())
    }
}

/// Writes one frame as a grey PNG: 8-bit formats (Mono8, 8-bit mosaics)
/// as 8-bit grey, the others (Mono12, Mono16, 12- and 16-bit mosaics) as
/// 16-bit grey with their values as they are (the manifest's `bits` says
/// 12 or 16); a mosaic's samples in place (of even width and height, as
/// the reader needs).
fn write_png(path: &Path, f: &BracketFrame<'_>) -> Result<()> {
    let (w, h) = (f.width as u32, f.height as u32);
    if f.format.is_bayer() && (w % 2 == 1 || h % 2 == 1) {
        bail!(
            "a {w}×{h} {} mosaic: a bracket folder holds Bayer mosaics of even width and height (choose another size or region)",
            f.format.genicam_name()
        );
    }
    match f.format {
        PixelFormat::Rgb8 => bail!(
            "pixel format {}: brackets hold grey images or Bayer mosaics",
            f.format.genicam_name()
        ),
        format if format.bits() == 8 => image::GrayImage::from_raw(w, h, f.data.to_vec())
            .context("a frame of the wrong size")?
            .save(path)?,
        _ => {
            let px: Vec<u16> = f
                .data
                .chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]))
                .collect();
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, px)
                .context("a frame of the wrong size")?
                .save(path)?;
        }
    }
    Ok(())
}

/// Writes a bracket sequence of the simulated rig `render` into `dir`:
/// its calibration, and for every moment and camera the frame the
/// simulated camera takes at each level (with the noise of that moment),
/// in the layout [`BracketSource`] reads. `tick` is called per image.
pub fn export(
    render: &rigview_core::sim::SimRender,
    spec: &ExportSpec,
    dir: &Path,
    tick: &mut dyn FnMut(),
) -> Result<()> {
    use rigview_core::sim::FillRequest;
    let names: Vec<String> = render.cameras().iter().map(|c| c.name.clone()).collect();
    let title = format!(
        "rigview exposure brackets of the simulated rig \"{}\": {} moments, {} exposures each",
        render.config().name,
        spec.frames,
        spec.levels.len(),
    );
    let mut writer = BracketWriter::create(dir, Some(render.rig()), &names, &title)?;
    for n in 0..spec.frames {
        let t = render.time_of(n as u64);
        let mut images = Vec::new();
        for (i, info) in render.cameras().iter().enumerate() {
            for &level in &spec.levels {
                let setting = ExposureSetting {
                    shutter_us: level,
                    gain_db: 0.0,
                };
                let req =
                    FillRequest::new(i, n as u64, setting, info.format, info.width, info.height);
                let mut buf = vec![0u8; req.buffer_len()];
                render.fill(&req, &mut buf)?;
                images.push((i, setting, info, buf));
                tick();
            }
        }
        let frames: Vec<BracketFrame<'_>> = images
            .iter()
            .map(|(i, setting, info, buf)| BracketFrame {
                camera: *i,
                setting: *setting,
                format: info.format,
                width: info.width,
                height: info.height,
                data: buf,
            })
            .collect();
        writer.write_moment(t, &frames)?;
    }
    Ok(())
}
