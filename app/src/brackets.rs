//! Exposure brackets: for every moment and camera, images of the same
//! scene at several exposures, and a frame source that answers each
//! camera's command with the image nearest to it, so that a controller can
//! be run in closed loop on real scenes (the paper's protocol). See
//! `docs/brackets.md` for the folder layout.
//!
//! ```text
//! DIR/
//!   brackets.csv          the manifest: camera,moment,time_s,exposure_us,gain_db,file
//!   rig.yaml              the rig's calibration (any format `rigview calib` reads)
//!   front/000000_00.png   the images (8-bit or 16-bit grey PNG), paths relative to DIR
//! ```
//!
//! [`BracketSource`] gives one set per moment. Each camera's command takes
//! effect after one frame of latency, as on the simulated rig, and is
//! answered with the bracket whose exposure level `shutter · gain` is
//! nearest in log exposure; the frame's metadata carries that bracket's
//! exposure time and gain, so the controller sees the bracket's
//! quantisation.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use rigview_core::exposure::{ExposureRange, ExposureSetting, PixelFormat};
use rigview_core::source::{
    check_command, CameraInfo, ExposureCommand, Frame, FrameMeta, FrameSet, FrameSource,
    FrameStatus, SourceError, StreamHealth,
};

/// The manifest's file name.
pub const MANIFEST: &str = "brackets.csv";
/// The calibration's file name.
pub const RIG: &str = "rig.yaml";
/// The manifest's columns, in order.
pub const COLUMNS: [&str; 6] = [
    "camera",
    "moment",
    "time_s",
    "exposure_us",
    "gain_db",
    "file",
];

/// One image of a bracket.
#[derive(Clone, Debug, PartialEq)]
pub struct BracketImage {
    /// What it was taken with.
    pub setting: ExposureSetting,
    /// Its path.
    pub file: PathBuf,
    /// Its line in the manifest.
    pub line: usize,
}

/// One moment: per camera, its images in ascending exposure.
#[derive(Clone, Debug, PartialEq)]
pub struct Moment {
    /// Seconds from the first moment.
    pub time_s: f64,
    /// Per camera (rig order), the bracket.
    pub cameras: Vec<Vec<BracketImage>>,
}

/// A read manifest.
#[derive(Clone, Debug, PartialEq)]
pub struct Manifest {
    /// The moments, in order.
    pub moments: Vec<Moment>,
}

/// Reads `dir`'s manifest for a rig of `cameras` (names, rig order).
/// Errors name the file and the line: a missing image, an unknown camera,
/// a duplicate, a number that does not parse, a moment without an image of
/// some camera.
pub fn read_manifest(dir: &Path, cameras: &[String]) -> Result<Manifest> {
    let path = dir.join(MANIFEST);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let at = |line: usize| format!("{} line {line}", path.display());
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let Some((n, header)) = lines.next() else {
        bail!(
            "{}: empty: expected the header {}",
            path.display(),
            COLUMNS.join(",")
        );
    };
    if header.split(',').map(str::trim).ne(COLUMNS) {
        bail!(
            "{}: expected the header {}, found \"{header}\"",
            at(n),
            COLUMNS.join(",")
        );
    }
    let mut moments: BTreeMap<usize, Moment> = BTreeMap::new();
    let mut seen: HashMap<(usize, usize, u64, u64), usize> = HashMap::new();
    for (n, line) in lines {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != COLUMNS.len() {
            bail!(
                "{}: {} fields, expected {} ({})",
                at(n),
                f.len(),
                COLUMNS.len(),
                COLUMNS.join(",")
            );
        }
        let camera = cameras.iter().position(|c| c == f[0]).with_context(|| {
            format!(
                "{}: camera \"{}\" is not in the rig ({})",
                at(n),
                f[0],
                cameras.join(", ")
            )
        })?;
        let number = |k: usize| -> Result<f64> {
            f[k].parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .with_context(|| format!("{}: {} \"{}\" is not a number", at(n), COLUMNS[k], f[k]))
        };
        let moment: usize = f[1]
            .parse()
            .with_context(|| format!("{}: moment \"{}\" is not a whole number ≥ 0", at(n), f[1]))?;
        let (time_s, shutter_us, gain_db) = (number(2)?, number(3)?, number(4)?);
        if shutter_us <= 0.0 {
            bail!(
                "{}: exposure_us {shutter_us}: expected a positive time",
                at(n)
            );
        }
        let file = dir.join(f[5]);
        if !file.is_file() {
            bail!("{}: the image {} does not exist", at(n), file.display());
        }
        let key = (camera, moment, shutter_us.to_bits(), gain_db.to_bits());
        if let Some(first) = seen.insert(key, n) {
            bail!(
                "{}: camera {}, moment {moment}, {shutter_us} µs at {gain_db} dB is given twice (first on line {first})",
                at(n),
                f[0]
            );
        }
        let m = moments.entry(moment).or_insert_with(|| Moment {
            time_s,
            cameras: vec![Vec::new(); cameras.len()],
        });
        if (m.time_s - time_s).abs() > 1e-9 {
            bail!(
                "{}: moment {moment} at {time_s} s, but at {} s on an earlier line",
                at(n),
                m.time_s
            );
        }
        m.cameras[camera].push(BracketImage {
            setting: ExposureSetting {
                shutter_us,
                gain_db,
            },
            file,
            line: n,
        });
    }
    if moments.is_empty() {
        bail!("{}: no images", path.display());
    }
    let moments = moments
        .into_iter()
        .enumerate()
        .map(|(k, (number, mut m))| {
            if number != k {
                bail!(
                    "{}: moment {k} has no images (moments are numbered from 0 without gaps)",
                    path.display()
                );
            }
            for (c, images) in m.cameras.iter_mut().enumerate() {
                if images.is_empty() {
                    bail!(
                        "{}: moment {k} has no image of camera {}",
                        path.display(),
                        cameras[c]
                    );
                }
                images.sort_by(|a, b| a.setting.exposure().total_cmp(&b.setting.exposure()));
            }
            Ok(m)
        })
        .collect::<Result<_>>()?;
    Ok(Manifest { moments })
}

/// The index of the image of `bracket` (ascending exposure) nearest to
/// `exposure` in log exposure (the darker of two equally near).
pub fn nearest(bracket: &[BracketImage], exposure: f64) -> usize {
    let target = exposure.max(f64::MIN_POSITIVE).ln();
    let mut best = (0, f64::INFINITY);
    for (k, b) in bracket.iter().enumerate() {
        let d = (b.setting.exposure().ln() - target).abs();
        if d < best.1 - 1e-12 {
            best = (k, d);
        }
    }
    best.0
}

/// The exposure levels of camera `cam`'s brackets when every moment has
/// the same (within 0.01 EV); `None` when they vary.
fn common_levels(manifest: &Manifest, cam: usize) -> Option<Vec<f64>> {
    let levels = |m: &Moment| -> Vec<f64> {
        m.cameras
            .get(cam)
            .map(|b| b.iter().map(|i| i.setting.exposure()).collect())
            .unwrap_or_default()
    };
    let first = levels(manifest.moments.first()?);
    manifest
        .moments
        .iter()
        .all(|m| {
            let l = levels(m);
            l.len() == first.len()
                && l.iter()
                    .zip(&first)
                    .all(|(a, b)| (a / b).log2().abs() <= 0.01)
        })
        .then_some(first)
}

/// Reads an image as a frame's pixels: 8-bit grey as Mono8, 16-bit grey as
/// Mono16; returns the format, width, height and pixels.
pub fn read_image(file: &Path) -> Result<(PixelFormat, usize, usize, Vec<u8>)> {
    let img = image::open(file).with_context(|| format!("reading the image {}", file.display()))?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    match img {
        image::DynamicImage::ImageLuma16(g) => {
            let data = g.into_raw().iter().flat_map(|v| v.to_le_bytes()).collect();
            Ok((PixelFormat::Mono16, w, h, data))
        }
        other => Ok((PixelFormat::Mono8, w, h, other.into_luma8().into_raw())),
    }
}

/// A bracket sequence as a frame source (see the module documentation).
#[derive(Debug)]
pub struct BracketSource {
    cameras: Vec<CameraInfo>,
    manifest: Manifest,
    settings: Vec<ExposureSetting>,
    queued: Vec<(u64, ExposureCommand)>,
    next: u64,
    health: Vec<StreamHealth>,
}

/// Frames between a command and the first frame that shows it.
const LATENCY: u64 = 1;

impl BracketSource {
    /// The sequence in `dir` for a rig of `names` (rig order); every
    /// camera starts at `start`.
    pub fn open(dir: &Path, names: &[String], start: ExposureSetting) -> Result<Self> {
        let manifest = read_manifest(dir, names)?;
        let first = &manifest.moments[0];
        let cameras = names
            .iter()
            .zip(&first.cameras)
            .enumerate()
            .map(|(cam, (name, images))| {
                let (format, width, height, _) = read_image(&images[0].file)?;
                Ok(CameraInfo {
                    name: name.clone(),
                    format,
                    width,
                    height,
                    range: ExposureRange::default(),
                    levels: common_levels(&manifest, cam),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            settings: vec![start; cameras.len()],
            health: vec![StreamHealth::default(); cameras.len()],
            cameras,
            manifest,
            queued: Vec::new(),
            next: 0,
        })
    }

    /// The manifest.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn produce(&mut self) -> Result<FrameSet> {
        let n = self.next;
        let (due, later): (Vec<_>, Vec<_>) = self.queued.drain(..).partition(|(at, _)| *at <= n);
        self.queued = later;
        for (_, c) in due {
            self.settings[c.camera] = c.setting;
        }
        let moment = &self.manifest.moments[n as usize];
        let timestamp_ns = (moment.time_s * 1e9).round().max(0.0) as u64;
        let mut frames = Vec::with_capacity(self.cameras.len());
        for (i, info) in self.cameras.iter().enumerate() {
            let bracket = &moment.cameras[i];
            let image = &bracket[nearest(bracket, self.settings[i].exposure())];
            let (format, width, height, data) = read_image(&image.file)?;
            if (format, width, height) != (info.format, info.width, info.height) {
                bail!(
                    "{}: a {width}×{height} {} image, but camera {}'s first image is {}×{} {}",
                    image.file.display(),
                    format.genicam_name(),
                    info.name,
                    info.width,
                    info.height,
                    info.format.genicam_name()
                );
            }
            let meta = FrameMeta {
                camera: i,
                format,
                width,
                height,
                taken: image.setting,
                timestamp_ns,
                frame_id: n,
                status: FrameStatus::Complete,
            };
            frames.push(Some(Frame::new(meta, data.into())?));
        }
        for h in &mut self.health {
            h.completed += 1;
        }
        self.next += 1;
        Ok(FrameSet {
            trigger: n,
            timestamp_ns,
            frames,
        })
    }
}

impl FrameSource for BracketSource {
    fn cameras(&self) -> &[CameraInfo] {
        &self.cameras
    }

    fn next_set(&mut self, _timeout: Duration) -> Result<Option<FrameSet>, SourceError> {
        if self.is_finished() {
            return Ok(None);
        }
        self.produce()
            .map(Some)
            .map_err(|e| SourceError::Failed(format!("{e:#}")))
    }

    fn apply(&mut self, commands: &[ExposureCommand]) -> Result<(), SourceError> {
        for c in commands {
            check_command(c, self.cameras.len())?;
            self.queued.push((self.next + LATENCY, *c));
        }
        Ok(())
    }

    fn health(&self) -> Vec<StreamHealth> {
        self.health.clone()
    }

    fn is_finished(&self) -> bool {
        self.next as usize >= self.manifest.moments.len()
    }
}

/// Opens the bracket sequence in `dir` with its calibration `dir/rig.yaml`
/// (or `rig`): the source and the rig.
pub fn open_with_rig(
    dir: &Path,
    rig: Option<&Path>,
    start: ExposureSetting,
) -> Result<(BracketSource, rigview_calib::rig::Rig)> {
    let rig_file = rig.map_or_else(|| dir.join(RIG), Path::to_path_buf);
    let loaded = rigview_calib::formats::load(&rig_file, None, None)
        .with_context(|| format!("loading the calibration {}", rig_file.display()))?;
    let names: Vec<String> = loaded.rig.cameras.iter().map(|c| c.name.clone()).collect();
    let source = BracketSource::open(dir, &names, start)?;
    Ok((source, loaded.rig))
}

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
        write!(manifest, "# {title}\n{}\n", COLUMNS.join(","))
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
    /// (Mono8 as 8-bit grey PNG; Mono12 and Mono16 as 16-bit grey, Mono12
    /// shifted to the top bits), then their lines of the manifest.
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
                "{name},{n},{time_s:.6},{:.3},{:.3},{file}\n",
                f.setting.shutter_us, f.setting.gain_db
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

/// Writes one frame as a grey PNG.
fn write_png(path: &Path, f: &BracketFrame<'_>) -> Result<()> {
    let (w, h) = (f.width as u32, f.height as u32);
    match f.format {
        PixelFormat::Mono8 => image::GrayImage::from_raw(w, h, f.data.to_vec())
            .context("a frame of the wrong size")?
            .save(path)?,
        PixelFormat::Mono12 | PixelFormat::Mono16 => {
            let scale = if f.format == PixelFormat::Mono12 {
                16
            } else {
                1
            };
            let px: Vec<u16> = f
                .data
                .chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]).saturating_mul(scale))
                .collect();
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, px)
                .context("a frame of the wrong size")?
                .save(path)?;
        }
        other => bail!(
            "pixel format {}: brackets hold grey images (Mono8, Mono12 or Mono16)",
            other.genicam_name()
        ),
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

#[cfg(test)]
mod tests {
    use super::*;

    fn setting(shutter_us: f64, gain_db: f64) -> ExposureSetting {
        ExposureSetting {
            shutter_us,
            gain_db,
        }
    }

    fn bracket(levels: &[f64]) -> Vec<BracketImage> {
        levels
            .iter()
            .enumerate()
            .map(|(k, &e)| BracketImage {
                setting: setting(e, 0.0),
                file: PathBuf::from(format!("{k}.png")),
                line: k + 2,
            })
            .collect()
    }

    #[test]
    fn the_nearest_exposure_is_nearest_in_log_exposure() {
        let b = bracket(&[1000.0, 2000.0, 4000.0]);
        assert_eq!(nearest(&b, 1000.0), 0);
        // 1400 is nearer 1000 than 2000 in log (ratios 1.40 and 1.43),
        // though nearer 2000 in µs.
        assert_eq!(nearest(&b, 1400.0), 0);
        assert_eq!(nearest(&b, 1430.0), 1);
        assert_eq!(nearest(&b, 1e9), 2);
        assert_eq!(nearest(&b, 1.0), 0);
        // Gain counts: 1000 µs at +6.02 dB is 2000.
        let mut g = b.clone();
        g[0].setting = setting(1000.0, 20.0 * 2f64.log10());
        g[1].setting = setting(3000.0, 0.0);
        assert_eq!(nearest(&g, 1900.0), 0);
    }

    fn write(dir: &Path, manifest: &str, images: &[&str]) {
        std::fs::create_dir_all(dir.join("front")).unwrap();
        for f in images {
            image::GrayImage::new(8, 6).save(dir.join(f)).unwrap();
        }
        std::fs::write(dir.join(MANIFEST), manifest).unwrap();
    }

    fn names() -> Vec<String> {
        vec!["front".into(), "left".into()]
    }

    const HEADER: &str = "camera,moment,time_s,exposure_us,gain_db,file\n";

    #[test]
    fn a_good_manifest_is_read_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let m = format!(
            "# two cameras, one moment\n{HEADER}front,0,0,2000,0,front/b.png\nfront,0,0,1000,0,front/a.png\nleft,0,0,1000,0,front/a.png\n"
        );
        write(dir.path(), &m, &["front/a.png", "front/b.png"]);
        let read = read_manifest(dir.path(), &names()).unwrap();
        assert_eq!(read.moments.len(), 1);
        let front = &read.moments[0].cameras[0];
        assert_eq!(front.len(), 2);
        assert!(front[0].setting.shutter_us < front[1].setting.shutter_us);
        assert_eq!(front[0].line, 4);
        let mut src = BracketSource::open(dir.path(), &names(), setting(1900.0, 0.0)).unwrap();
        let set = src.next_set(Duration::ZERO).unwrap().unwrap();
        let f = set.frames[0].as_ref().unwrap();
        assert!(
            (f.meta.taken.shutter_us - 2000.0).abs() < 1e-9,
            "{:?}",
            f.meta.taken
        );
        assert!(src.is_finished());
    }

    fn error(manifest: &str, images: &[&str]) -> String {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), manifest, images);
        format!("{:#}", read_manifest(dir.path(), &names()).unwrap_err())
    }

    #[test]
    fn manifest_errors_name_the_file_and_the_line() {
        let e = error(
            &format!("{HEADER}front,0,0,1000,0,front/a.png\nleft,0,0,1000,0,front/gone.png\n"),
            &["front/a.png"],
        );
        assert!(
            e.contains("brackets.csv line 3")
                && e.contains("gone.png")
                && e.contains("does not exist"),
            "{e}"
        );
        let e = error(
            &format!("{HEADER}front,0,0,1000,0,front/a.png\nfront,0,0,1000,0,front/a.png\nleft,0,0,1,0,front/a.png\n"),
            &["front/a.png"],
        );
        assert!(
            e.contains("line 3") && e.contains("twice") && e.contains("line 2"),
            "{e}"
        );
        let e = error(
            &format!("{HEADER}rear,0,0,1000,0,front/a.png\n"),
            &["front/a.png"],
        );
        assert!(
            e.contains("line 2") && e.contains("\"rear\" is not in the rig (front, left)"),
            "{e}"
        );
        let e = error(
            &format!("{HEADER}front,0,0,fast,0,front/a.png\n"),
            &["front/a.png"],
        );
        assert!(
            e.contains("line 2") && e.contains("exposure_us \"fast\""),
            "{e}"
        );
        let e = error(
            &format!("{HEADER}front,0,0,1000,0,front/a.png\nleft,0,0,1000,0,front/a.png\nfront,99999999999,0,1000,0,front/a.png\n"),
            &["front/a.png"],
        );
        assert!(e.contains("moment 1 has no images"), "{e}");
        let e = error("camera,moment\n", &[]);
        assert!(
            e.contains("line 1") && e.contains("expected the header"),
            "{e}"
        );
        let e = error(
            &format!("{HEADER}front,0,0,1000,0,front/a.png\n"),
            &["front/a.png"],
        );
        assert!(e.contains("moment 0 has no image of camera left"), "{e}");
    }
}
