//! Emulated frames for [`super::BracketSource`]: each camera's response and
//! sensor, the radiance of the current moment (merged once per moment and
//! camera), and the frame at the exposure asked.

use anyhow::{Context, Result};
use rigview_core::exposure::split::gain_factor;
use rigview_core::exposure::{ExposureRange, ExposureSetting, PixelFormat, ToneCurve};
use rigview_core::hdr::{self, EmulateOptions, MergeConfig, Radiance, Response, SensorNoise, Shot};
use rigview_core::sim::Sensor;

use super::{read_image, BracketImage, Decoded, Manifest, ResponseKind};

/// How far beyond its brackets (EV, each side) a camera's emulated
/// exposure reaches: below the shortest, samples clipped in every bracket
/// stay at the shortest's clip level scaled down; above the longest, the
/// dark samples carry the longest's noise scaled up.
pub const MARGIN_EV: f64 = 1.0;

/// Samples a response recovery solves for.
const RESPONSE_POINTS: usize = 300;
/// The smoothness of a recovered response (OpenCV's default).
const RESPONSE_LAMBDA: f64 = 10.0;

/// A merged moment of one camera.
#[derive(Clone, Debug)]
struct Merged {
    moment: usize,
    radiance: Radiance,
    format: PixelFormat,
    width: usize,
    height: usize,
}

/// Per camera: the response, the sensor, the span of its brackets and the
/// radiance of the moment last asked for.
#[derive(Debug)]
pub struct Emulator {
    seed: u64,
    sensor: Sensor,
    responses: Vec<Response>,
    spans: Vec<(f64, f64)>,
    cache: Vec<Option<Merged>>,
}

impl Emulator {
    /// The emulation of `manifest`'s cameras: the sensor from the defaults
    /// (`rigview_core::sim::Sensor`: 10 000 e⁻ full well, 12 e⁻ read noise)
    /// or the manifest's `# full_well_e:` and `# read_noise_e:`; a linear
    /// response above 8 bits or under `# response: linear`, else the
    /// response recovered from each camera's brackets of the first moment.
    pub fn new(manifest: &Manifest, seed: u64) -> Result<Self> {
        let mut sensor = Sensor::default();
        if let Some(v) = manifest.sensor.full_well_e {
            sensor.full_well_e = v;
        }
        if let Some(v) = manifest.sensor.read_noise_e {
            sensor.read_noise_e = v;
        }
        let responses = responses(manifest)?;
        let cameras = responses.len();
        let spans = (0..cameras)
            .map(|cam| {
                manifest
                    .moments
                    .iter()
                    .fold((f64::MAX, 0.0f64), |(lo, hi), m| {
                        let b = &m.cameras[cam];
                        (
                            lo.min(b[0].setting.exposure()),
                            hi.max(b[b.len() - 1].setting.exposure()),
                        )
                    })
            })
            .collect();
        Ok(Self {
            seed,
            sensor,
            responses,
            spans,
            cache: vec![None; cameras],
        })
    }

    /// Camera `cam`'s response.
    pub(super) fn response(&self, cam: usize) -> &Response {
        &self.responses[cam]
    }

    /// The sensor emulated.
    pub(super) fn sensor(&self) -> &Sensor {
        &self.sensor
    }

    /// The exposure range camera `cam` reports: shutter over the span of its
    /// brackets (all moments) widened by [`MARGIN_EV`], gain 0 – 24 dB; the
    /// level emulated is clamped to the same span.
    pub fn range(&self, cam: usize) -> ExposureRange {
        let (lo, hi) = self.spans[cam];
        ExposureRange {
            shutter_min_us: lo * (-MARGIN_EV).exp2(),
            shutter_max_us: hi * MARGIN_EV.exp2(),
            gain_min_db: 0.0,
            gain_max_db: 24.0,
        }
    }

    /// `setting` with its level clamped to `[lo, hi]`: gain lowered first,
    /// then the shutter.
    fn clamp(setting: &ExposureSetting, lo: f64, hi: f64) -> ExposureSetting {
        let e = setting.exposure();
        let mut s = *setting;
        if e > hi {
            let over_db = 20.0 * (e / hi).log10();
            s.gain_db = (s.gain_db - over_db).max(s.gain_db.min(0.0));
            s.shutter_us = (hi / gain_factor(s.gain_db)).min(s.shutter_us);
        } else if e < lo {
            s.shutter_us = lo / gain_factor(s.gain_db);
        }
        s
    }

    /// Camera `cam`'s frame of moment `moment` at `setting` (clamped): the
    /// setting emulated and the frame.
    pub fn frame(
        &mut self,
        manifest: &Manifest,
        moment: usize,
        cam: usize,
        setting: &ExposureSetting,
    ) -> Result<(ExposureSetting, Decoded)> {
        self.frame_with(manifest, moment, cam, setting, true)
    }

    /// [`Self::frame`], with the sensor's noise or without it (`noise`
    /// false: the expected frame, as the dense sweep of `rigview eval
    /// --brackets` scores it).
    pub fn frame_with(
        &mut self,
        manifest: &Manifest,
        moment: usize,
        cam: usize,
        setting: &ExposureSetting,
        noise: bool,
    ) -> Result<(ExposureSetting, Decoded)> {
        let fresh = !matches!(&self.cache[cam], Some(m) if m.moment == moment);
        if fresh {
            let images: Vec<&BracketImage> = manifest.moments[moment].cameras[cam].iter().collect();
            let (radiance, d) =
                merge_images(manifest, &images, &self.responses[cam], &self.sensor)?;
            self.cache[cam] = Some(Merged {
                moment,
                radiance,
                format: d.format,
                width: d.width,
                height: d.height,
            });
        }
        let m = self.cache[cam]
            .as_ref()
            .context("the emulator's radiance of the moment")?;
        let (lo, hi) = m.radiance.span();
        let taken = Self::clamp(setting, lo * (-MARGIN_EV).exp2(), hi * MARGIN_EV.exp2());
        let mut data = vec![0u8; m.radiance.len() * m.radiance.bytes_per_sample()];
        let options = EmulateOptions {
            noise,
            seed: self.seed,
            camera: cam,
            frame: moment as u64,
        };
        m.radiance
            .emulate(&taken, &options, &mut data)
            .with_context(|| format!("emulating camera {cam} of moment {moment} at {taken:?}"))?;
        Ok((
            taken,
            Decoded {
                format: m.format,
                width: m.width,
                height: m.height,
                data,
            },
        ))
    }
}

/// The noise of `sensor` at the depth of `format`.
pub(super) fn noise_of(sensor: &Sensor, format: PixelFormat) -> Result<SensorNoise> {
    Ok(SensorNoise::of(sensor, format.bits())?)
}

/// Merges `images` (of one camera and moment, same layout) under
/// `response`: the radiance and the first image (for its layout).
pub(super) fn merge_images(
    manifest: &Manifest,
    images: &[&BracketImage],
    response: &Response,
    sensor: &Sensor,
) -> Result<(Radiance, Decoded)> {
    let decoded: Vec<Decoded> = images
        .iter()
        .map(|i| read_image(manifest, i))
        .collect::<Result<_>>()?;
    let radiance = merge_decoded(manifest, images, &decoded, response, sensor)?;
    let first = decoded
        .into_iter()
        .next()
        .context("merging a bracket without images")?;
    Ok((radiance, first))
}

/// Merges already decoded `images` (their `decoded` pixels).
pub(super) fn merge_decoded(
    manifest: &Manifest,
    images: &[&BracketImage],
    decoded: &[Decoded],
    response: &Response,
    sensor: &Sensor,
) -> Result<Radiance> {
    let first = decoded
        .first()
        .context("merging a bracket without images")?;
    for (i, d) in images.iter().zip(decoded) {
        if (d.format, d.width, d.height) != (first.format, first.width, first.height) {
            anyhow::bail!(
                "{}: a {}×{} {} image in a bracket of {}×{} {} images",
                manifest.at(i),
                d.width,
                d.height,
                d.format.genicam_name(),
                first.width,
                first.height,
                first.format.genicam_name()
            );
        }
    }
    let shots: Vec<Shot<'_>> = images
        .iter()
        .zip(decoded)
        .map(|(i, d)| Shot {
            setting: i.setting,
            data: &d.data,
        })
        .collect();
    let config = MergeConfig {
        response: response.clone(),
        ..MergeConfig::new(first.width * first.height, noise_of(sensor, first.format)?)
    };
    hdr::merge(&shots, &config).with_context(|| {
        format!(
            "{}: merging the bracket of line {}",
            manifest.path.display(),
            images.first().map_or(0, |i| i.line)
        )
    })
}

/// Recovers an 8-bit response from one camera's bracket.
/// Each camera's response: linear above 8 bits or under `# response:
/// linear`, else recovered from its brackets of the first moment.
pub(super) fn responses(manifest: &Manifest) -> Result<Vec<Response>> {
    let first = &manifest.moments[0];
    let mut responses = Vec::with_capacity(first.cameras.len());
    for images in &first.cameras {
        let linear = match manifest.sensor.response {
            Some(ResponseKind::Linear) => true,
            Some(ResponseKind::Recover) => false,
            None => read_image(manifest, &images[0])?.format.bits() > 8,
        };
        responses.push(if linear {
            Response::Linear
        } else {
            recover(manifest, images)?
        });
    }
    Ok(responses)
}

/// The tone curve scale-and-clip simulates through for a camera of
/// `response`: none for a linear one.
pub(super) fn tone_curve(response: &Response) -> Result<Option<ToneCurve>> {
    Ok(match response {
        Response::Linear => None,
        Response::Curve { inverse, .. } => Some(ToneCurve::from_code_values(inverse)?),
    })
}

fn recover(manifest: &Manifest, images: &[BracketImage]) -> Result<Response> {
    let decoded: Vec<Decoded> = images
        .iter()
        .map(|i| read_image(manifest, i))
        .collect::<Result<_>>()?;
    let samples = decoded.iter().map(|d| d.data.len()).min().unwrap_or(0);
    let shots: Vec<Shot<'_>> = images
        .iter()
        .zip(&decoded)
        .map(|(i, d)| Shot {
            setting: i.setting,
            data: &d.data,
        })
        .collect();
    Response::recover(&shots, samples, RESPONSE_POINTS, RESPONSE_LAMBDA).with_context(|| {
        format!(
            "{}: recovering the response of the bracket of line {} (say `# response: linear` for linear data)",
            manifest.path.display(),
            images.first().map_or(0, |i| i.line)
        )
    })
}
