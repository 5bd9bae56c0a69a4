//! Calibration file formats: what each reads and writes, and the one entry
//! point that tells them apart ([`load`], [`save`]).
//!
//! | format | reads | writes | one file holds |
//! | --- | --- | --- | --- |
//! | [`rig_yaml`] rigview rig (`.yaml`) | yes | yes | a rig |
//! | [`opencv`] OpenCV FileStorage (`.yaml`, `.xml`) | yes | yes | a camera |
//! | [`surround`] surround layout (a folder of 4 OpenCV files) | yes | — | a camera each |
//! | [`kalibr`] Kalibr camchain | yes | yes | a rig (frame of cam0) |
//! | [`ros`] ROS camera_info (ROS 1 YAML; ROS 2 message as echoed) | yes | ROS 1 | a camera |
//!
//! A folder reads as a rig of its per-camera files (OpenCV or ROS; camera
//! names from the file names), or, if it holds `front`, `left`, `back` and
//! `right` with the surround keys, as the surround layout with poses
//! recovered from the ground.
//!
//! The OpenCV formats and the surround layout need the crate's `opencv`
//! feature (on by default); without it, their files are still told apart
//! ([`detect`]) but reading or writing one is a
//! [`CalibError::NeedsFeature`] that names the file.

pub mod basalt;
pub mod camodocal;
pub mod kalibr;
pub mod ocamcalib;
#[cfg(feature = "opencv")]
pub mod opencv;
pub mod rig_yaml;
pub mod ros;
#[cfg(feature = "opencv")]
pub mod surround;
pub mod woodscape;
pub(crate) mod yaml;

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::error::{CalibError, Result};
use crate::model::ModelKind;
use crate::rig::{Camera, Frame, Rig};

/// A calibration file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Format {
    /// rigview's rig YAML.
    Rig,
    /// OpenCV FileStorage YAML (one file a camera).
    #[cfg_attr(feature = "clap", value(name = "opencv-yaml"))]
    OpenCvYaml,
    /// OpenCV FileStorage XML (one file a camera).
    #[cfg_attr(feature = "clap", value(name = "opencv-xml"))]
    OpenCvXml,
    /// Kalibr camchain YAML.
    Kalibr,
    /// ROS camera_info (one file a camera): ROS 1's YAML, or a ROS 2
    /// CameraInfo message as `ros2 topic echo` prints it (read only).
    Ros,
    /// WoodScape's calibration JSON (one file a camera, with its pose).
    #[cfg_attr(feature = "clap", value(name = "woodscape"))]
    WoodScape,
    /// OCamCalib's `calib_results.txt` (one file a camera, no pose).
    #[cfg_attr(feature = "clap", value(name = "ocamcalib"))]
    OcamCalib,
    /// camodocal's camera YAML (MEI, KANNALA_BRANDT, PINHOLE; one file a
    /// camera, no pose).
    Camodocal,
    /// Basalt's calibration JSON (a rig posed on an IMU).
    Basalt,
}

impl Format {
    /// Every format.
    pub const ALL: [Format; 9] = [
        Format::Rig,
        Format::OpenCvYaml,
        Format::OpenCvXml,
        Format::Kalibr,
        Format::Ros,
        Format::WoodScape,
        Format::OcamCalib,
        Format::Camodocal,
        Format::Basalt,
    ];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Format::Rig => "rig",
            Format::OpenCvYaml => "opencv-yaml",
            Format::OpenCvXml => "opencv-xml",
            Format::Kalibr => "kalibr",
            Format::Ros => "ros",
            Format::WoodScape => "woodscape",
            Format::OcamCalib => "ocamcalib",
            Format::Camodocal => "camodocal",
            Format::Basalt => "basalt",
        }
    }

    /// Whether one file holds one camera (else a whole rig).
    pub fn per_camera(self) -> bool {
        matches!(
            self,
            Format::OpenCvYaml
                | Format::OpenCvXml
                | Format::Ros
                | Format::WoodScape
                | Format::OcamCalib
                | Format::Camodocal
        )
    }

    fn extension(self) -> &'static str {
        match self {
            Format::OpenCvXml => "xml",
            Format::WoodScape => "json",
            Format::OcamCalib => "txt",
            Format::Basalt => "json",
            _ => "yaml",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Format {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        Format::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Format::ALL.iter().map(|f| f.name()).collect();
                format!("unknown format \"{s}\" (known: {})", names.join(", "))
            })
    }
}

/// What [`load`] read.
#[derive(Clone, Debug, PartialEq)]
pub struct Loaded {
    /// The rig.
    pub rig: Rig,
    /// The format of the file (or of the folder's files).
    pub format: Format,
    /// For the surround layout: how well each recovered pose fits.
    #[cfg(feature = "opencv")]
    pub surround: Option<surround::SurroundImport>,
}

/// What an OpenCV file holds besides its camera (the surround keys).
#[cfg(feature = "opencv")]
type OpenCvExtra = opencv::OpenCvCamera;
/// (Without OpenCV no file of it is read.)
#[cfg(not(feature = "opencv"))]
type OpenCvExtra = std::convert::Infallible;

/// The error for a file of an OpenCV format when the `opencv` feature is
/// off.
#[cfg(not(feature = "opencv"))]
fn needs_opencv(file: String, format: Format) -> CalibError {
    CalibError::NeedsFeature {
        file,
        format: format!("OpenCV FileStorage ({format})"),
        feature: "opencv",
    }
}

/// Reads a file as UTF-8 text; errors name the file.
pub fn read_text(path: &Path) -> Result<String> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| CalibError::Io {
        file: file.clone(),
        source,
    })?;
    String::from_utf8(bytes).map_err(|e| CalibError::Parse {
        file,
        detail: format!(
            "not UTF-8 text (invalid byte at offset {}); expected a calibration file",
            e.utf8_error().valid_up_to()
        ),
    })
}

fn has_extension(path: &Path, exts: &[&str]) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

/// Tells a file's format from its contents (and, for XML, its name). A
/// `%YAML:1.0` first line alone does not make a file OpenCV's: Kalibr and
/// ROS files written by some tools begin with it too, so the keys decide.
pub fn detect(path: &Path, text: &str) -> Result<Format> {
    let file = path.display().to_string();
    let head = text.trim_start_matches('\u{feff}').trim_start();
    let directive = head.starts_with("%YAML");
    if ocamcalib::looks_like(text) {
        return Ok(Format::OcamCalib);
    }
    if text.contains("!!opencv-matrix") {
        return Ok(Format::OpenCvYaml);
    }
    if head.starts_with("<?xml") || head.starts_with("<opencv_storage") {
        return Ok(Format::OpenCvXml);
    }
    if !directive && has_extension(path, &["xml"]) {
        return Ok(Format::OpenCvXml);
    }
    let doc = match yaml::parse(text, &file) {
        Ok(doc) => doc,
        // OpenCV's reader says what is wrong with the files it writes.
        Err(_) if directive => return Ok(Format::OpenCvYaml),
        Err(e) => return Err(e),
    };
    let key = |k: &str| doc.get(k).is_some();
    // ROS writes K as a map {rows, cols, data}; OpenCV as a matrix or list.
    let ros_matrix = matches!(
        doc.get("camera_matrix"),
        None | Some(serde_norway::Value::Mapping(_))
    );
    let ros_message = doc.as_mapping().is_some_and(ros::is_message);
    if woodscape::is_woodscape(&doc) {
        Ok(Format::WoodScape)
    } else if key("model_type") {
        Ok(Format::Camodocal)
    } else if key("value0") {
        Ok(Format::Basalt)
    } else if key("format") {
        Ok(Format::Rig)
    } else if key("cam0") {
        Ok(Format::Kalibr)
    } else if (key("image_width") || key("distortion_model") || ros_message) && ros_matrix {
        Ok(Format::Ros)
    } else if key("camera_matrix") || directive {
        Ok(Format::OpenCvYaml)
    } else {
        Err(CalibError::Format {
            file,
            detail: "cannot tell the calibration format: expected a rigview rig \
                     (format: rigview-rig), a Kalibr camchain (cam0: …), a ROS camera_info \
                     (image_width: … or a ROS 2 message with width, k, d), a WoodScape \
                     calibration (intrinsic, extrinsic), a camodocal camera (model_type), a \
                     Basalt calibration (value0), an OCamCalib calib_results.txt or an OpenCV \
                     FileStorage file (camera_matrix, %YAML:1.0 or <?xml)"
                .into(),
        })
    }
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("camera")
        .to_owned()
}

/// Reads one camera file (OpenCV or ROS) as a camera named after the file
/// (OpenCV) or its `camera_name` (ROS).
fn load_camera(
    path: &Path,
    text: &str,
    format: Format,
    model: Option<ModelKind>,
) -> Result<(Camera, Option<OpenCvExtra>)> {
    let file = path.display().to_string();
    match format {
        #[cfg(feature = "opencv")]
        Format::OpenCvYaml | Format::OpenCvXml => {
            let c = opencv::parse(text, format == Format::OpenCvXml, &file, model)?;
            let cam = Camera {
                name: stem(path),
                device: None,
                intrinsics: c.intrinsics,
                pose: c.pose,
            };
            Ok((cam, Some(c)))
        }
        #[cfg(not(feature = "opencv"))]
        Format::OpenCvYaml | Format::OpenCvXml => {
            let _ = (text, model);
            Err(needs_opencv(file, format))
        }
        Format::Ros => Ok((ros::parse(text, &file, &stem(path))?, None)),
        Format::WoodScape => Ok((woodscape::parse(text, &file, &stem(path))?, None)),
        Format::OcamCalib => Ok((ocamcalib::parse(text, &file, &stem(path))?, None)),
        Format::Camodocal => Ok((camodocal::parse(text, &file, &stem(path))?, None)),
        Format::Rig | Format::Kalibr | Format::Basalt => Err(CalibError::Format {
            file,
            detail: format!("a {format} file holds a rig, not one camera of a folder"),
        }),
    }
}

/// Loads a calibration: a file of any format, or a folder of per-camera
/// files. `format` overrides detection; `model` is the camera model for
/// OpenCV files that do not say.
pub fn load(path: &Path, format: Option<Format>, model: Option<ModelKind>) -> Result<Loaded> {
    let file = path.display().to_string();
    if path.is_dir() {
        return load_dir(path, format, model);
    }
    let text = read_text(path)?;
    let format = match format {
        Some(f) => f,
        None => detect(path, &text)?,
    };
    let rig = match format {
        Format::Rig => rig_yaml::parse(&text, &file)?,
        Format::Kalibr => kalibr::parse(&text, &file)?,
        Format::Basalt => basalt::parse(&text, &file)?,
        Format::OpenCvYaml
        | Format::OpenCvXml
        | Format::Ros
        | Format::WoodScape
        | Format::OcamCalib
        | Format::Camodocal => {
            let (cam, _) = load_camera(path, &text, format, model)?;
            Rig::new(Frame::Vehicle, vec![cam], vec![]).map_err(|e| e.in_file(&file))?
        }
    };
    Ok(Loaded {
        rig,
        format,
        #[cfg(feature = "opencv")]
        surround: None,
    })
}

fn load_dir(dir: &Path, format: Option<Format>, model: Option<ModelKind>) -> Result<Loaded> {
    let name = dir.display().to_string();
    let entries = std::fs::read_dir(dir).map_err(|source| CalibError::Io {
        file: name.clone(),
        source,
    })?;
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && has_extension(p, &["yaml", "yml", "xml", "json", "txt"]))
        .collect();
    paths.sort();
    if paths.is_empty() {
        return Err(CalibError::Format {
            file: name,
            detail:
                "the folder holds no .yaml, .yml, .xml, .json or OCamCalib .txt calibration files"
                    .into(),
        });
    }
    let mut cameras = Vec::new();
    let mut opencv_files = Vec::new();
    let mut seen = None;
    for p in &paths {
        let text = read_text(p)?;
        // Text files beside the calibration (a README) are not cameras.
        if has_extension(p, &["txt"]) && !ocamcalib::looks_like(&text) {
            continue;
        }
        let f = match format {
            Some(f) => f,
            None => detect(p, &text)?,
        };
        let (cam, cv) = load_camera(p, &text, f, model)?;
        seen.get_or_insert(f);
        if let Some(cv) = cv {
            opencv_files.push((cam.name.clone(), p.display().to_string(), cv));
        }
        cameras.push(cam);
    }
    let format = seen.unwrap_or(Format::OpenCvYaml);
    #[cfg(feature = "opencv")]
    {
        let is_surround = surround::CAMERAS.iter().all(|n| {
            opencv_files
                .iter()
                .any(|(c, _, f)| c == n && f.surround.is_some())
        });
        if is_surround {
            let imp = surround::import(&opencv_files)?;
            return Ok(Loaded {
                rig: imp.rig.clone(),
                format,
                surround: Some(imp),
            });
        }
    }
    #[cfg(not(feature = "opencv"))]
    let _ = opencv_files;
    let rig = Rig::new(Frame::Vehicle, cameras, vec![]).map_err(|e| e.in_file(&name))?;
    Ok(Loaded {
        rig,
        format,
        #[cfg(feature = "opencv")]
        surround: None,
    })
}

/// The format to write to a path when none is named: `.xml` is OpenCV XML,
/// anything else rigview's rig YAML.
pub fn output_format(path: &Path) -> Format {
    if has_extension(path, &["xml"]) {
        Format::OpenCvXml
    } else {
        Format::Rig
    }
}

fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|source| CalibError::Io {
        file: path.display().to_string(),
        source,
    })
}

/// The rig as the text of a whole-rig format, or of one camera of a
/// per-camera format (without the `opencv` feature, OpenCV's formats are a
/// [`CalibError::NeedsFeature`] naming the camera).
pub fn to_text(rig: &Rig, format: Format, camera: usize) -> Result<String> {
    let cam = rig
        .cameras
        .get(camera)
        .ok_or_else(|| CalibError::Argument(format!("no camera {camera} in the rig")))?;
    match format {
        Format::Rig => rig_yaml::to_string(rig),
        Format::Kalibr => kalibr::write(rig),
        #[cfg(feature = "opencv")]
        Format::OpenCvYaml => opencv::write(cam, false),
        #[cfg(feature = "opencv")]
        Format::OpenCvXml => opencv::write(cam, true),
        #[cfg(not(feature = "opencv"))]
        Format::OpenCvYaml | Format::OpenCvXml => {
            Err(needs_opencv(format!("camera \"{}\"", cam.name), format))
        }
        Format::Ros => ros::write(cam),
        Format::WoodScape => woodscape::write(cam),
        Format::OcamCalib => ocamcalib::write(cam),
        Format::Camodocal => camodocal::write(cam),
        Format::Basalt => basalt::write(rig),
    }
}

/// Saves a rig. Whole-rig formats write `path`. Per-camera formats write
/// `path` itself for a one-camera rig; otherwise `path` must contain
/// `{camera}` (replaced by each name) or be a folder (existing, or ending
/// in `/`), which gets `NAME.yaml` / `NAME.xml` per camera. Returns the
/// files written.
pub fn save(rig: &Rig, path: &Path, format: Option<Format>) -> Result<Vec<PathBuf>> {
    let format = format.unwrap_or_else(|| output_format(path));
    #[cfg(not(feature = "opencv"))]
    if matches!(format, Format::OpenCvYaml | Format::OpenCvXml) {
        return Err(needs_opencv(path.display().to_string(), format));
    }
    if !format.per_camera() {
        write_file(path, &to_text(rig, format, 0)?)?;
        return Ok(vec![path.to_owned()]);
    }
    let s = path.to_string_lossy();
    let is_dir = path.is_dir() || s.ends_with('/');
    let targets: Vec<PathBuf> = if s.contains("{camera}") {
        rig.cameras
            .iter()
            .map(|c| PathBuf::from(s.replace("{camera}", &c.name)))
            .collect()
    } else if is_dir {
        std::fs::create_dir_all(path).map_err(|source| CalibError::Io {
            file: s.to_string(),
            source,
        })?;
        rig.cameras
            .iter()
            .map(|c| path.join(format!("{}.{}", c.name, format.extension())))
            .collect()
    } else if rig.cameras.len() == 1 {
        vec![path.to_owned()]
    } else {
        return Err(CalibError::Argument(format!(
            "{s}: {format} holds one camera a file and the rig has {}: give a folder or a path \
             with {{camera}} in it",
            rig.cameras.len()
        )));
    };
    for (i, t) in targets.iter().enumerate() {
        write_file(t, &to_text(rig, format, i)?)?;
    }
    Ok(targets)
}

/// Without the `opencv` feature (run by `tests/tests/opencv_optional.rs`,
/// which builds this crate alone without it).
#[cfg(all(test, not(feature = "opencv")))]
mod without_opencv {
    use super::*;
    use crate::model::{Distortion, Intrinsics};

    fn needs_opencv_naming(e: &CalibError, file: &Path) {
        assert!(
            matches!(
                e,
                CalibError::NeedsFeature {
                    feature: "opencv",
                    ..
                }
            ),
            "{e:?}"
        );
        let msg = e.to_string();
        assert!(msg.starts_with(&file.display().to_string()), "{msg}");
        assert!(msg.contains("OpenCV FileStorage"), "{msg}");
        assert!(msg.contains("`opencv` feature"), "{msg}");
    }

    #[test]
    fn opencv_files_need_the_opencv_feature_and_other_formats_work() {
        let d =
            std::env::temp_dir().join(format!("rigview-calib-no-opencv-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let yaml = d.join("front.yaml");
        std::fs::write(
            &yaml,
            "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 300., 0., 320., 0., 300., 240., 0., 0., 1. ]\n",
        )
        .unwrap();
        let xml = d.join("left.xml");
        std::fs::write(
            &xml,
            "<?xml version=\"1.0\"?>\n<opencv_storage>\n<resolution>640 480</resolution>\n</opencv_storage>\n",
        )
        .unwrap();
        for file in [&yaml, &xml] {
            needs_opencv_naming(&load(file, None, None).unwrap_err(), file);
        }
        // A folder of them: the first file read is named.
        needs_opencv_naming(&load(&d, None, None).unwrap_err(), &yaml);

        let k = Intrinsics {
            width: 640,
            height: 480,
            fx: 300.0,
            fy: 300.0,
            cx: 320.0,
            cy: 240.0,
            distortion: Distortion::RadTan([0.0; 5]),
        };
        let rig = Rig::new(Frame::Vehicle, vec![Camera::new("front", k)], vec![]).unwrap();
        let out = d.join("written.xml");
        needs_opencv_naming(&save(&rig, &out, None).unwrap_err(), &out);
        assert!(!out.exists());
        // rigview's own format and ROS's need no OpenCV.
        let rig_file = d.join("rig.yaml");
        save(&rig, &rig_file, None).unwrap();
        assert_eq!(load(&rig_file, None, None).unwrap().rig, rig);
        let ros = d.join("ros.yaml");
        save(&rig, &ros, Some(Format::Ros)).unwrap();
        assert_eq!(load(&ros, None, None).unwrap().format, Format::Ros);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
