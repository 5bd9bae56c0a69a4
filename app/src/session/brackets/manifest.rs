//! The manifest of a bracket folder and its images (docs/brackets.md).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use rigview_core::exposure::{ExposureSetting, PixelFormat};
use rigview_core::image::BAYER_PATTERNS;

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
/// The optional columns, after [`COLUMNS`], in any order.
pub const OPTIONAL: [&str; 2] = ["pattern", "bits"];

/// How an image's values are laid out, as the manifest declares it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Layout {
    /// The Bayer pattern (`RGGB`, `GRBG`, `GBRG`, `BGGR`), `None` for grey.
    pub pattern: Option<&'static str>,
    /// The values' bits (8, 12 or 16), `None` for the PNG's depth.
    pub bits: Option<u32>,
}

/// How the values relate to the light (`# response:`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResponseKind {
    /// Proportional (raw sensor data).
    Linear,
    /// To be recovered from the brackets (Debevec–Malik; 8-bit only).
    Recover,
}

/// What the manifest's header comments say of the sensor (`# key: value`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorNotes {
    /// `# response: linear|recover`; `None`: linear above 8 bits,
    /// recovered at 8.
    pub response: Option<ResponseKind>,
    /// `# full_well_e: N`, electrons.
    pub full_well_e: Option<f64>,
    /// `# read_noise_e: N`, electrons rms.
    pub read_noise_e: Option<f64>,
}

/// One image of a bracket.
#[derive(Clone, Debug, PartialEq)]
pub struct BracketImage {
    /// What it was taken with.
    pub setting: ExposureSetting,
    /// Its path.
    pub file: PathBuf,
    /// Its line in the manifest.
    pub line: usize,
    /// Its declared layout.
    pub layout: Layout,
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
    /// The manifest's path.
    pub path: PathBuf,
    /// The moments, in order.
    pub moments: Vec<Moment>,
    /// The sensor, as the header comments describe it.
    pub sensor: SensorNotes,
}

impl Manifest {
    /// "DIR/brackets.csv line N", for errors about `image`.
    pub fn at(&self, image: &BracketImage) -> String {
        format!("{} line {}", self.path.display(), image.line)
    }
}

/// A Bayer pattern's canonical name.
fn pattern(text: &str) -> Option<&'static str> {
    BAYER_PATTERNS
        .iter()
        .find(|p| p.eq_ignore_ascii_case(text))
        .copied()
}

/// Parses a layout field (`pattern` or `bits`) into `layout`; empty keeps
/// it.
fn layout_field(layout: &mut Layout, key: &str, value: &str) -> Result<(), String> {
    if value.is_empty() {
        return Ok(());
    }
    match key {
        "pattern" if value.eq_ignore_ascii_case("mono") => layout.pattern = None,
        "pattern" => {
            layout.pattern = Some(pattern(value).ok_or_else(|| {
                format!(
                    "pattern \"{value}\": expected mono or a Bayer pattern ({})",
                    BAYER_PATTERNS.join(", ")
                )
            })?);
        }
        _ => {
            layout.bits = Some(
                value
                    .parse()
                    .ok()
                    .filter(|b| [8, 12, 16].contains(b))
                    .ok_or_else(|| format!("bits \"{value}\": expected 8, 12 or 16"))?,
            );
        }
    }
    Ok(())
}

/// Reads `dir`'s manifest for a rig of `cameras` (names, rig order).
/// Errors name the file and the line: a missing image, an unknown camera,
/// a duplicate, a number that does not parse, a pattern or a bit depth
/// that is none, a moment without an image of some camera.
pub fn read_manifest(dir: &Path, cameras: &[String]) -> Result<Manifest> {
    let path = dir.join(MANIFEST);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let at = |line: usize| format!("{} line {line}", path.display());
    // Header comments: `# key: value` for the layout's defaults and the
    // sensor; other comments are free text.
    let mut defaults = Layout::default();
    let mut sensor = SensorNotes {
        response: None,
        full_well_e: None,
        read_noise_e: None,
    };
    for (n, line) in text.lines().enumerate().map(|(k, l)| (k + 1, l.trim())) {
        let Some(comment) = line.strip_prefix('#') else {
            if line.is_empty() {
                continue;
            }
            break;
        };
        let Some((key, value)) = comment.split_once(':') else {
            continue;
        };
        let (key, value) = (key.trim(), value.trim());
        let positive = |v: &str| -> Result<f64> {
            v.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v > 0.0)
                .with_context(|| format!("{}: {key} \"{v}\": expected a positive number", at(n)))
        };
        match key {
            "pattern" | "bits" => layout_field(&mut defaults, key, value)
                .map_err(|e| anyhow::anyhow!("{}: {e}", at(n)))?,
            "response" => {
                sensor.response = Some(match value {
                    "linear" => ResponseKind::Linear,
                    "recover" => ResponseKind::Recover,
                    _ => bail!(
                        "{}: response \"{value}\": expected linear or recover",
                        at(n)
                    ),
                });
            }
            "full_well_e" => sensor.full_well_e = Some(positive(value)?),
            "read_noise_e" => sensor.read_noise_e = Some(positive(value)?),
            _ => {}
        }
    }
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
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let extra = names.get(COLUMNS.len()..).unwrap_or_default();
    let mut seen_extra: Vec<&str> = Vec::new();
    let extra_ok = extra.iter().all(|c| {
        let fresh = OPTIONAL.contains(c) && !seen_extra.contains(c);
        seen_extra.push(*c);
        fresh
    });
    if names.len() < COLUMNS.len() || names[..COLUMNS.len()] != COLUMNS || !extra_ok {
        bail!(
            "{}: expected the header {} (then optionally {}), found \"{header}\"",
            at(n),
            COLUMNS.join(","),
            OPTIONAL.join(", ")
        );
    }
    let width = names.len();
    let mut moments: BTreeMap<usize, Moment> = BTreeMap::new();
    let mut seen: HashMap<(usize, usize, u64, u64), usize> = HashMap::new();
    for (n, line) in lines {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != width {
            bail!(
                "{}: {} fields, expected {} ({})",
                at(n),
                f.len(),
                width,
                names.join(",")
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
        let mut layout = defaults;
        for (key, value) in extra.iter().zip(&f[COLUMNS.len()..]) {
            layout_field(&mut layout, key, value).map_err(|e| anyhow::anyhow!("{}: {e}", at(n)))?;
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
            layout,
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
    Ok(Manifest {
        path,
        moments,
        sensor,
    })
}

/// A decoded image: its format, size and samples (the format's layout).
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    /// The pixel format.
    pub format: PixelFormat,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The samples.
    pub data: Vec<u8>,
}

/// Reads a PNG as a frame's pixels: 8-bit grey as Mono8, 16-bit grey as
/// Mono16 (returns the format, width, height and pixels).
pub fn read_png(file: &Path) -> Result<Decoded> {
    let img = image::open(file).with_context(|| format!("reading the image {}", file.display()))?;
    let (width, height) = (img.width() as usize, img.height() as usize);
    let (format, data) = match img {
        image::DynamicImage::ImageLuma16(g) => (
            PixelFormat::Mono16,
            g.into_raw().iter().flat_map(|v| v.to_le_bytes()).collect(),
        ),
        other => (PixelFormat::Mono8, other.into_luma8().into_raw()),
    };
    Ok(Decoded {
        format,
        width,
        height,
        data,
    })
}

/// Reads `image` of `manifest` in its declared layout: a grey PNG of 8
/// bits (Mono8, or an 8-bit mosaic) or 16 (Mono16/Mono12, or a 16- or
/// 12-bit mosaic). Errors name the manifest's line: a depth that is not
/// the PNG's, values above the declared bits, a mosaic of odd size.
pub fn read_image(manifest: &Manifest, image: &BracketImage) -> Result<Decoded> {
    let mut d = read_png(&image.file).with_context(|| manifest.at(image))?;
    let png_bits = d.format.bits();
    let bits = image.layout.bits.unwrap_or(png_bits);
    let fits = if png_bits == 8 { bits == 8 } else { bits > 8 };
    if !fits {
        bail!(
            "{}: bits {bits}, but {} is a {png_bits}-bit PNG (expected {})",
            manifest.at(image),
            image.file.display(),
            if png_bits == 8 { "8" } else { "12 or 16" }
        );
    }
    if bits == 12 {
        if let Some(v) = d
            .data
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .find(|&v| v > 4095)
        {
            bail!(
                "{}: bits 12, but {} holds the value {v} (at most 4095 in 12 bits; a 12-bit image scaled to the top of 16 bits is bits 16)",
                manifest.at(image),
                image.file.display()
            );
        }
    }
    d.format = match image.layout.pattern {
        Some(p) => {
            if d.width % 2 == 1 || d.height % 2 == 1 || d.width < 2 || d.height < 2 {
                bail!(
                    "{}: pattern {p}, but {} is {}×{}: a Bayer mosaic needs an even width and height",
                    manifest.at(image),
                    image.file.display(),
                    d.width,
                    d.height
                );
            }
            PixelFormat::bayer(p, bits)
                .with_context(|| format!("{}: pattern {p} at {bits} bits", manifest.at(image)))?
        }
        None if bits == 12 => PixelFormat::Mono12,
        None => d.format,
    };
    Ok(d)
}
