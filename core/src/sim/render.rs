//! The simulated cameras' images: ray-traced once, exposed every frame.
//!
//! [`SimRender::new`] traces, for every camera and every pixel,
//! `supersample²` rays through the camera model into the scene and stores
//! the two parts of the sensor irradiance ([`super::scene`]: the part that
//! scales with the sun and the part that scales with the sky, vignetting
//! included) and what the pixel sees ([`Class`]). A frame then costs only
//! exposure, gain, noise and quantisation ([`SimRender::fill`]): the
//! scripted illumination at the frame's time scales the two parts.
//!
//! A `SimRender` is immutable, `Send` and `Sync`: put it in an `Arc` and
//! fill buffers from any thread (a GenICam fake camera's callback, the
//! simulated rig's source, tests).

use nalgebra::{Point2, Vector3};
use rand::Rng;
use rigview_calib::{Camera, Frame as RigFrame, Rig};

use super::config::{RigChoice, SimConfig};
use super::rig::{reference_rig, scale_rig};
use super::scene::{Built, Class, Hit, Shade};
use super::script::{Levels, Script};
use super::sensor::{
    expose_row, format_bits, frame_rng, noise_table, store_row, Sensor, NOISE_TABLE_LEN,
};
use crate::error::{Error, Result};
use crate::exposure::ExposureSetting;
use crate::image::PixelFormat;
use crate::source::{CameraInfo, FrameMeta, FrameStatus};

/// One camera's precomputed image.
#[derive(Clone, Debug)]
struct Planes {
    width: usize,
    height: usize,
    sun: Vec<f32>,
    sky: Vec<f32>,
    class: Vec<u8>,
}

/// What to render into a buffer: see [`SimRender::fill`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FillRequest {
    /// The camera's index in the rig.
    pub camera: usize,
    /// The frame counter: it picks the noise and, unless `time_s` is given,
    /// the moment (`frame / trigger_hz`).
    pub frame: u64,
    /// The moment in the script, seconds (`None`: from `frame`).
    pub time_s: Option<f64>,
    /// Exposure time (µs) and gain (dB).
    pub setting: ExposureSetting,
    /// The buffer's pixel format: Mono8, Mono12 and Mono16 (unpacked,
    /// little-endian; 8, 12 and 16 bits), RGB8 and the 8-bit Bayer formats
    /// (grey in every channel and site).
    pub format: PixelFormat,
    /// The buffer's width in pixels; another size than the camera's
    /// resamples its image (nearest pixel).
    pub width: usize,
    /// The buffer's height in pixels.
    pub height: usize,
    /// Whether to add noise (also off when the sensor's `noise` is off).
    pub noise: bool,
}

impl FillRequest {
    /// A request for a noisy frame at the moment of `frame`.
    pub fn new(
        camera: usize,
        frame: u64,
        setting: ExposureSetting,
        format: PixelFormat,
        width: usize,
        height: usize,
    ) -> Self {
        Self {
            camera,
            frame,
            time_s: None,
            setting,
            format,
            width,
            height,
            noise: true,
        }
    }

    /// The bytes the buffer needs.
    pub fn buffer_len(&self) -> usize {
        self.width * self.height * self.format.bytes_per_pixel()
    }
}

/// The simulated rig's cameras, precomputed (see the module documentation).
#[derive(Clone, Debug)]
pub struct SimRender {
    config: SimConfig,
    rig: Rig,
    built: Built,
    planes: Vec<Planes>,
    infos: Vec<CameraInfo>,
}

/// Loads the rig a configuration names.
pub fn load_rig(choice: &RigChoice) -> Result<Rig> {
    match choice {
        RigChoice::Reference => reference_rig(),
        RigChoice::File(p) => rigview_calib::formats::load(p, None, None)
            .map(|l| l.rig)
            .map_err(|e| Error::calibration("the simulated rig", e)),
    }
}

impl SimRender {
    /// Loads the rig and traces every camera.
    pub fn new(config: &SimConfig) -> Result<Self> {
        config.validate()?;
        Self::with_rig(config, load_rig(&config.rig)?)
    }

    /// Traces every camera of `rig` (the configuration's `rig` is ignored).
    /// Every camera needs a pose in the vehicle frame, outside the vehicle
    /// and the obstacles.
    pub fn with_rig(config: &SimConfig, rig: Rig) -> Result<Self> {
        config.validate()?;
        if rig.frame != RigFrame::Vehicle {
            return Err(Error::invalid(
                &config.name,
                "the simulated rig's frame",
                "poses in the vehicle frame (x forward, y left, z up, ground z = 0)",
                "poses relative to a camera",
            ));
        }
        let rig = scale_rig(&rig, config.scale)?;
        let built = Built::new(&config.scene)?;
        for c in &rig.cameras {
            let Some(pose) = &c.pose else {
                return Err(Error::invalid(
                    &config.name,
                    format!("camera \"{}\"'s pose", c.name),
                    "every camera's pose in the vehicle frame",
                    "none",
                ));
            };
            let t = pose.translation();
            if t.z <= 0.0 || built.inside(t) {
                return Err(Error::invalid(
                    &config.name,
                    format!("camera \"{}\"'s position", c.name),
                    "above the ground and outside the vehicle and the scene's obstacles",
                    format_args!("({:.2}, {:.2}, {:.2}) m", t.x, t.y, t.z),
                ));
            }
        }
        let half_fov = 0.5 * config.lens_fov_deg.to_radians();
        let planes = rig
            .cameras
            .iter()
            .map(|c| {
                trace_camera(
                    &built,
                    c,
                    config.supersample,
                    half_fov,
                    config.sensor.vignetting,
                )
            })
            .collect::<Vec<_>>();
        let infos = rig
            .cameras
            .iter()
            .zip(&planes)
            .map(|(c, p)| CameraInfo {
                name: c.name.clone(),
                format: config.sensor.format(),
                width: p.width,
                height: p.height,
                range: config.sensor.range(),
                levels: None,
                tone_curve: None,
            })
            .collect();
        Ok(Self {
            config: config.clone(),
            rig,
            built,
            planes,
            infos,
        })
    }

    /// The configuration it was built from.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The rig, at the rendered resolution: its calibration is exact.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// The cameras as a frame source reports them.
    pub fn cameras(&self) -> &[CameraInfo] {
        &self.infos
    }

    /// The camera model.
    pub fn sensor(&self) -> &Sensor {
        &self.config.sensor
    }

    /// The illumination script.
    pub fn script(&self) -> &Script {
        &self.config.script
    }

    /// The moment of frame `frame`, seconds.
    pub fn time_of(&self, frame: u64) -> f64 {
        frame as f64 / self.config.trigger_hz
    }

    /// The light at `t` seconds.
    pub fn levels(&self, t: f64) -> Levels {
        self.config.script.levels(t)
    }

    /// The direction to the sun (unit vector, vehicle frame).
    pub fn sun_direction(&self) -> Vector3<f64> {
        self.built.sun_dir()
    }

    /// The scene point (vehicle frame) that the ray from `origin` along
    /// `direction` sees first, or `None` for the sky: the truth behind a
    /// match between two cameras.
    pub fn scene_point(
        &self,
        origin: &Vector3<f64>,
        direction: &Vector3<f64>,
    ) -> Option<Vector3<f64>> {
        let d = direction.try_normalize(1e-12)?;
        match self.built.first_hit(origin, &d) {
            Hit::Sky => None,
            Hit::Ground(t) | Hit::Solid(t, ..) => Some(origin + t * d),
        }
    }

    fn planes(&self, camera: usize) -> Result<&Planes> {
        self.planes.get(camera).ok_or(Error::CameraIndex {
            index: camera,
            count: self.planes.len(),
        })
    }

    /// Camera `camera`'s sensor irradiance at `t` seconds, row-major at its
    /// rendered size (radiance units, vignetting included, noise-free and
    /// not clipped): the truth behind its frames.
    pub fn irradiance(&self, camera: usize, t: f64) -> Result<Vec<f32>> {
        let p = self.planes(camera)?;
        let l = self.levels(t);
        let (a, b) = (l.sun as f32, l.sky as f32);
        Ok(p.sun
            .iter()
            .zip(&p.sky)
            .map(|(&s, &k)| a * s + b * k)
            .collect())
    }

    /// Camera `camera`'s two precomputed parts of the sensor irradiance,
    /// row-major at its rendered size: the part that scales with the sun and
    /// the part that scales with the sky (see [`super::scene`]). A frame at
    /// `t` sees `levels(t).sun · sun + levels(t).sky · sky`.
    pub fn light_parts(&self, camera: usize) -> Result<(&[f32], &[f32])> {
        let p = self.planes(camera)?;
        Ok((&p.sun, &p.sky))
    }

    /// What pixel (x, y) of a camera sees (`None` off the image).
    pub fn class(&self, camera: usize, x: usize, y: usize) -> Option<Class> {
        let p = self.planes.get(camera)?;
        (x < p.width && y < p.height).then(|| Class::from_u8(p.class[y * p.width + x]))
    }

    /// Renders one frame of one camera into `buf` (the first
    /// [`FillRequest::buffer_len`] bytes, rows tightly packed) and returns
    /// its metadata. A pure function of the request: the same request gives
    /// the same bytes, from any thread.
    ///
    /// This is what a GenICam fake camera's fill callback calls (Aravis's
    /// `arv_fake_camera_set_fill_pattern`): convert the callback's exposure
    /// and gain to µs and dB, pass its frame counter and buffer.
    pub fn fill(&self, req: &FillRequest, buf: &mut [u8]) -> Result<FrameMeta> {
        let p = self.planes(req.camera)?;
        let (w, h) = (req.width, req.height);
        if w == 0 || h == 0 {
            return Err(Error::EmptyImage {
                what: "simulated frame",
                width: w,
                height: h,
            });
        }
        if w > NOISE_TABLE_LEN / 2 {
            return Err(Error::InvalidParameter {
                name: "width",
                value: w as f64,
                expected: "at most 524288 pixels a row",
            });
        }
        let s = req.setting;
        if !(s.shutter_us.is_finite() && s.shutter_us > 0.0 && s.gain_db.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "setting",
                value: s.shutter_us,
                expected: "a positive exposure time in µs and a finite gain in dB",
            });
        }
        let bpp = req.format.bytes_per_pixel();
        let row_bytes = w * bpp;
        if buf.len() < row_bytes * h {
            return Err(Error::BufferSize {
                what: "simulated frame",
                expected: row_bytes * h,
                actual: buf.len(),
                detail: format!("{} {w}×{h}", req.format.genicam_name()),
            });
        }
        let t = req.time_s.unwrap_or_else(|| self.time_of(req.frame));
        let levels = self.levels(t);
        let noise = req.noise && self.config.sensor.noise;
        let gains =
            self.config
                .sensor
                .gains(&s, levels.sun, levels.sky, format_bits(req.format), noise);
        let table = noise_table();
        let mut rng = frame_rng(self.config.seed, req.camera, req.frame);
        let mut dn = vec![0f32; w];
        let same = (w, h) == (p.width, p.height);
        let xs: Vec<usize> = if same {
            Vec::new()
        } else {
            (0..w)
                .map(|x| (((x as f64 + 0.5) * p.width as f64 / w as f64) as usize).min(p.width - 1))
                .collect()
        };
        let (mut sun_row, mut sky_row) = (vec![0f32; w], vec![0f32; w]);
        for (y, out) in buf.chunks_exact_mut(row_bytes).take(h).enumerate() {
            let sy = if same {
                y
            } else {
                (((y as f64 + 0.5) * p.height as f64 / h as f64) as usize).min(p.height - 1)
            };
            let src = sy * p.width..(sy + 1) * p.width;
            let (sun, sky) = if same {
                (&p.sun[src.clone()], &p.sky[src])
            } else {
                let (ps, pk) = (&p.sun[src.clone()], &p.sky[src]);
                for ((a, b), &x) in sun_row.iter_mut().zip(sky_row.iter_mut()).zip(&xs) {
                    *a = ps[x];
                    *b = pk[x];
                }
                (&sun_row[..], &sky_row[..])
            };
            let off = if noise {
                rng.gen_range(0..NOISE_TABLE_LEN - w)
            } else {
                0
            };
            expose_row(&gains, sun, sky, &table[off..off + w], &mut dn);
            store_row(req.format, &dn, out);
        }
        Ok(FrameMeta {
            camera: req.camera,
            format: req.format,
            width: w,
            height: h,
            taken: s,
            timestamp_ns: (t * 1e9).round().max(0.0) as u64,
            frame_id: req.frame,
            status: FrameStatus::Complete,
        })
    }

    /// [`SimRender::fill`] into a new buffer of the camera's own size and
    /// format.
    pub fn render(
        &self,
        camera: usize,
        frame: u64,
        setting: ExposureSetting,
        noise: bool,
    ) -> Result<crate::source::Frame> {
        let info = self.infos.get(camera).ok_or(Error::CameraIndex {
            index: camera,
            count: self.infos.len(),
        })?;
        let req = FillRequest {
            noise,
            ..FillRequest::new(camera, frame, setting, info.format, info.width, info.height)
        };
        let mut buf = vec![0u8; req.buffer_len()];
        let meta = self.fill(&req, &mut buf)?;
        crate::source::Frame::new(meta, buf.into())
    }
}

/// Pixel-to-ray for the fisheye model through tables of `sin θ / θd` and
/// `cos θ` against `θd`, built from the model's own projection: linear
/// interpolation between 8192 entries keeps rays within about 1e-9 rad of
/// [`rigview_calib::Intrinsics::unproject`] (tested), at a fraction of the
/// cost of its Newton iteration. Other models use `unproject`.
#[derive(Clone, Debug)]
pub(crate) struct RayTable {
    k: rigview_calib::Intrinsics,
    /// `θd` step of the tables and the largest `θd` covered.
    step: f64,
    td_max: f64,
    sin_over_td: Vec<f64>,
    cos: Vec<f64>,
}

impl RayTable {
    const ENTRIES: usize = 8192;

    /// Tables up to `theta_max` from the axis (`None`: not a fisheye, or the
    /// model does not reach that far).
    pub(crate) fn new(k: &rigview_calib::Intrinsics, theta_max: f64) -> Option<Self> {
        if !matches!(k.distortion, rigview_calib::Distortion::Fisheye(_)) {
            return None;
        }
        let theta_max = theta_max.min(k.max_incidence() * (1.0 - 1e-9));
        // θd(θ) from the model: project a point at θ in the x–z plane.
        let td_of = |theta: f64| {
            let (s, c) = theta.sin_cos();
            k.project(&Vector3::new(s, 0.0, c))
                .map(|p| (p.x - k.cx) / k.fx)
        };
        let td_max = td_of(theta_max)?;
        let fine = 8 * Self::ENTRIES;
        let samples: Vec<(f64, f64)> = (0..=fine)
            .map(|i| {
                let theta = theta_max * i as f64 / fine as f64;
                td_of(theta).map(|td| (td, theta))
            })
            .collect::<Option<_>>()?;
        let step = td_max / Self::ENTRIES as f64;
        let mut sin_over_td = Vec::with_capacity(Self::ENTRIES + 2);
        let mut cos = Vec::with_capacity(Self::ENTRIES + 2);
        let mut at = 0;
        for j in 0..=Self::ENTRIES + 1 {
            let td = (j as f64 * step).min(td_max);
            while at + 2 < samples.len() && samples[at + 1].0 < td {
                at += 1;
            }
            let ((t0, a0), (t1, a1)) = (samples[at], samples[at + 1]);
            let theta = a0 + (a1 - a0) * ((td - t0) / (t1 - t0)).clamp(0.0, 1.0);
            // sin θ / θd → 1 / θd'(0) = 1 at the centre.
            sin_over_td.push(if td > 0.0 { theta.sin() / td } else { 1.0 });
            cos.push(theta.cos());
        }
        Some(Self {
            k: *k,
            step,
            td_max,
            sin_over_td,
            cos,
        })
    }

    /// The unit ray of pixel position `(u, v)` in the camera frame, `None`
    /// beyond the table.
    #[inline]
    pub(crate) fn ray(&self, u: f64, v: f64) -> Option<Vector3<f64>> {
        let xd = (u - self.k.cx) / self.k.fx;
        let yd = (v - self.k.cy) / self.k.fy;
        let td = (xd * xd + yd * yd).sqrt();
        if td.is_nan() || td > self.td_max {
            return None;
        }
        let f = td / self.step;
        let i = (f as usize).min(Self::ENTRIES);
        let t = f - i as f64;
        let s = self.sin_over_td[i] + (self.sin_over_td[i + 1] - self.sin_over_td[i]) * t;
        let c = self.cos[i] + (self.cos[i + 1] - self.cos[i]) * t;
        Some(Vector3::new(s * xd, s * yd, c))
    }
}

/// Rays of one camera into the scene.
struct Sampler<'a> {
    built: &'a Built,
    k: &'a rigview_calib::Intrinsics,
    table: Option<RayTable>,
    rot: nalgebra::Matrix3<f64>,
    o: Vector3<f64>,
    cos_half_fov: f64,
}

impl Sampler<'_> {
    /// The camera-frame ray of a pixel position inside the lens's field.
    fn ray(&self, u: f64, v: f64) -> Option<Vector3<f64>> {
        let ray = match &self.table {
            Some(t) => t.ray(u, v),
            None => self.k.unproject(&Point2::new(u, v)).map(|r| r.into_inner()),
        }?;
        (ray.z >= self.cos_half_fov).then_some(ray)
    }

    /// The light from one pixel position (nothing outside the field).
    fn sample(&self, u: f64, v: f64, pixel: f64) -> (Shade, Class) {
        match self.ray(u, v) {
            Some(r) => self.built.shade(&self.o, &(self.rot * r), pixel),
            None => (Shade::default(), Class::Outside),
        }
    }
}

/// Runs `f(y, sun_row, sky_row, class_row)` on every row, the rows spread
/// over the machine's threads in turn (so that cheap sky rows and dear
/// ground rows spread evenly).
fn for_rows<F>(w: usize, sun: &mut [f32], sky: &mut [f32], class: &mut [u8], f: F)
where
    F: Fn(usize, &mut [f32], &mut [f32], &mut [u8]) + Sync,
{
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, 16);
    type Row<'r> = (usize, &'r mut [f32], &'r mut [f32], &'r mut [u8]);
    let mut jobs: Vec<Vec<Row<'_>>> = (0..threads).map(|_| Vec::new()).collect();
    for (y, ((s, k), c)) in sun
        .chunks_exact_mut(w)
        .zip(sky.chunks_exact_mut(w))
        .zip(class.chunks_exact_mut(w))
        .enumerate()
    {
        jobs[y % threads].push((y, s, k, c));
    }
    std::thread::scope(|scope| {
        for job in jobs {
            let f = &f;
            scope.spawn(move || {
                for (y, s, k, c) in job {
                    f(y, s, k, c);
                }
            });
        }
    });
}

/// Relative difference above which a pixel is supersampled.
const REFINE: f32 = 0.08;

/// Traces one camera: a ray through every pixel's centre, then
/// `supersample²` rays through the pixels that differ from a neighbour by
/// more than [`REFINE`] or see something else (edges, shadow boundaries,
/// the rim of the lens's field); vignetting last.
fn trace_camera(built: &Built, cam: &Camera, ss: u32, half_fov: f64, vignetting: f64) -> Planes {
    let k = &cam.intrinsics;
    let (w, h) = (k.width as usize, k.height as usize);
    let mut sun = vec![0f32; w * h];
    let mut sky = vec![0f32; w * h];
    let mut class = vec![0u8; w * h];
    let Some(pose) = cam.pose else {
        return Planes {
            width: w,
            height: h,
            sun,
            sky,
            class,
        };
    };
    let sampler = Sampler {
        built,
        k,
        // A little beyond the lens's field, so that edge samples are decided
        // by the field, not the table.
        table: RayTable::new(k, half_fov + 0.01),
        rot: *pose.rotation_matrix(),
        o: *pose.translation(),
        cos_half_fov: half_fov.cos(),
    };
    let pixel = 1.0 / k.fx.max(k.fy);
    for_rows(w, &mut sun, &mut sky, &mut class, |y, sun, sky, class| {
        for x in 0..w {
            let (s, c) = sampler.sample(x as f64, y as f64, pixel);
            sun[x] = s.sun as f32;
            sky[x] = s.sky as f32;
            class[x] = c as u8;
        }
    });
    let (centre_sun, centre_sky, centre_class) = (sun.clone(), sky.clone(), class.clone());
    let differs = |a: usize, b: usize| {
        let (la, lb) = (centre_sun[a] + centre_sky[a], centre_sun[b] + centre_sky[b]);
        centre_class[a] != centre_class[b] || (la - lb).abs() > REFINE * la.max(lb)
    };
    let ssf = f64::from(ss.max(1));
    for_rows(w, &mut sun, &mut sky, &mut class, |y, sun, sky, _| {
        for x in 0..w {
            let i = y * w + x;
            let refine = ss > 1
                && ((x > 0 && differs(i, i - 1))
                    || (x + 1 < w && differs(i, i + 1))
                    || (y > 0 && differs(i, i - w))
                    || (y + 1 < h && differs(i, i + w)));
            if refine {
                let mut acc = Shade::default();
                for sy in 0..ss {
                    for sx in 0..ss {
                        let (s, _) = sampler.sample(
                            x as f64 - 0.5 + (f64::from(sx) + 0.5) / ssf,
                            y as f64 - 0.5 + (f64::from(sy) + 0.5) / ssf,
                            pixel / ssf,
                        );
                        acc.sun += s.sun;
                        acc.sky += s.sky;
                    }
                }
                sun[x] = (acc.sun / (ssf * ssf)) as f32;
                sky[x] = (acc.sky / (ssf * ssf)) as f32;
            }
            if vignetting > 0.0 {
                if let Some(r) = sampler.ray(x as f64, y as f64) {
                    let theta = r.z.clamp(-1.0, 1.0).acos();
                    let v = (1.0 - vignetting * (theta / half_fov).powi(2)) as f32;
                    sun[x] *= v;
                    sky[x] *= v;
                }
            }
        }
    });
    Planes {
        width: w,
        height: h,
        sun,
        sky,
        class,
    }
}

#[cfg(test)]
mod tests;
