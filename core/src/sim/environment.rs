//! Real scenes for the simulated rig: an equirectangular radiance map (an
//! HDR panorama photographed from one point) in place of the procedural
//! world.
//!
//! The map's upper half is the sky, at infinity. Its lower half is the
//! ground as the panorama's camera saw it from `height_m` above the ground:
//! a ray of the rig that hits the ground plane at `p` takes the map's
//! radiance in the direction from `(0, 0, height_m)` to `p`. Every camera of
//! the rig sees the same ground point with the same radiance, so the
//! bird's-eye view of a map is seamless where its ground is flat; walls and
//! trees near the horizon lie painted on the far ground.
//!
//! Only the rig's own vehicle is shaded as the procedural scene shades it
//! (by the scene's `sun` and `sky`). The map's radiance is the `sky` part of
//! [`super::scene`]'s light, so the illumination script's `sky` (or `all`)
//! events scale it.
//!
//! # Orientation
//!
//! The map's centre column looks along the vehicle's +x (forward) when
//! `yaw_deg` is 0; columns to its right look to the vehicle's right, as a
//! panorama looks from inside. Row 0 is the zenith. `yaw_deg` turns the map
//! counter-clockwise seen from above (the azimuth its centre column looks
//! along).

use std::path::Path;

use nalgebra::Vector3;

use crate::error::{Error, Result};

/// A luminance map over all directions, equirectangular.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// Rec. 709 luminance, row-major.
    luminance: Vec<f32>,
}

impl EnvironmentMap {
    /// Reads a radiance map: any floating-point image the `image` crate
    /// reads (Radiance `.hdr`). Colour maps are reduced to Rec. 709
    /// luminance. Errors name the file.
    pub fn load(path: &Path) -> Result<Self> {
        let file = path.display().to_string();
        let err = |detail: String| Error::File {
            file: file.clone(),
            detail,
        };
        let image = image::ImageReader::open(path)
            .map_err(|e| err(format!("cannot read the environment map: {e}")))?
            .with_guessed_format()
            .map_err(|e| err(format!("cannot read the environment map: {e}")))?
            .decode()
            .map_err(|e| {
                err(format!(
                    "cannot decode the environment map (expected a Radiance .hdr radiance map): {e}"
                ))
            })?;
        match image.color() {
            image::ColorType::Rgb32F | image::ColorType::Rgba32F => {}
            other => {
                return Err(err(format!(
                    "expected a radiance map of linear floating-point values (Radiance .hdr), \
                     found {other:?} pixels: a display-referred image has lost the light's range"
                )))
            }
        }
        let rgb = image.into_rgb32f();
        let (w, h) = rgb.dimensions();
        let luminance = rgb
            .pixels()
            .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
            .collect();
        Self::from_luminance(w as usize, h as usize, luminance).map_err(|e| match e {
            Error::Invalid {
                field,
                expected,
                found,
                ..
            } => err(format!("{field}: expected {expected}, found {found}")),
            other => other,
        })
    }

    /// A map from its luminance, row-major, `width = 2·height` or any other
    /// shape of at least 2×2; values finite and not negative, not all zero.
    pub fn from_luminance(width: usize, height: usize, luminance: Vec<f32>) -> Result<Self> {
        let what = "the environment map";
        if width < 2 || height < 2 || luminance.len() != width * height {
            return Err(Error::invalid(
                what,
                "size",
                "at least 2×2 pixels, one value per pixel",
                format_args!("{width}×{height} with {} values", luminance.len()),
            ));
        }
        if let Some(k) = luminance.iter().position(|v| !v.is_finite() || *v < 0.0) {
            return Err(Error::invalid(
                what,
                format!("pixel ({}, {})", k % width, k / width),
                "a finite radiance, not negative",
                luminance[k],
            ));
        }
        if luminance.iter().all(|v| *v == 0.0) {
            return Err(Error::invalid(what, "pixels", "some light", "black"));
        }
        Ok(Self {
            width,
            height,
            luminance,
        })
    }

    /// Width in pixels (all azimuths).
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels (zenith to nadir).
    pub fn height(&self) -> usize {
        self.height
    }

    /// The luminance in direction `d` (vehicle frame, any length but 0),
    /// the map turned by `yaw` radians: bilinear between pixel centres,
    /// wrapping in azimuth.
    pub fn radiance(&self, d: &Vector3<f64>, yaw: f64) -> f64 {
        let n = d.norm();
        if n.is_nan() || n <= 0.0 {
            return 0.0;
        }
        let azimuth = d.y.atan2(d.x) - yaw;
        let elevation = (d.z / n).clamp(-1.0, 1.0).asin();
        let tau = std::f64::consts::TAU;
        let u = (0.5 - azimuth / tau).rem_euclid(1.0) * self.width as f64 - 0.5;
        let v = (0.5 - elevation / std::f64::consts::PI) * self.height as f64 - 0.5;
        let v = v.clamp(0.0, (self.height - 1) as f64);
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let col = |k: f64| (k as i64).rem_euclid(self.width as i64) as usize;
        let (c0, c1) = (col(u0), col(u0 + 1.0));
        let r0 = v0 as usize;
        let r1 = (r0 + 1).min(self.height - 1);
        let at = |r: usize, c: usize| f64::from(self.luminance[r * self.width + c]);
        let top = at(r0, c0) + fu * (at(r0, c1) - at(r0, c0));
        let bottom = at(r1, c0) + fu * (at(r1, c1) - at(r1, c0));
        top + fv * (bottom - top)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 8×4 map whose pixel (c, r) holds `1 + c + 10·r`.
    fn ramp() -> EnvironmentMap {
        let (w, h) = (8, 4);
        let l = (0..w * h)
            .map(|k| (1 + k % w + 10 * (k / w)) as f32)
            .collect();
        EnvironmentMap::from_luminance(w, h, l).expect("a valid map")
    }

    fn dir(azimuth_deg: f64, elevation_deg: f64) -> Vector3<f64> {
        let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        Vector3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
    }

    #[test]
    fn directions_fall_on_their_pixels() {
        let m = ramp();
        // Pixel centres: column c looks at azimuth 180° − (c + 0.5)·45°,
        // row r at elevation 90° − (r + 0.5)·45°.
        for c in 0..8 {
            for r in 0..4 {
                let az = 180.0 - (f64::from(c) + 0.5) * 45.0;
                let el = 90.0 - (f64::from(r) + 0.5) * 45.0;
                let want = f64::from(1 + c + 10 * r);
                let got = m.radiance(&dir(az, el), 0.0);
                assert!((got - want).abs() < 1e-9, "({c}, {r}): {got} != {want}");
            }
        }
        // Forward (+x) is the centre of the map: between columns 3 and 4.
        assert!((m.radiance(&dir(0.0, 22.5), 0.0) - 14.5).abs() < 1e-9);
        // To the right (−y) lies right of the centre: column 5.5.
        assert!((m.radiance(&dir(-90.0, 22.5), 0.0) - 16.5).abs() < 1e-9);
        // Turning the map by 45° moves what was at azimuth 0 to 45°.
        let turned = m.radiance(&dir(45.0, 22.5), 45f64.to_radians());
        assert!((turned - 14.5).abs() < 1e-9);
    }

    #[test]
    fn azimuth_wraps_and_the_poles_hold() {
        let m = ramp();
        // Straight back: between column 7 and column 0 of the same row.
        let back = m.radiance(&dir(180.0, 22.5), 0.0);
        assert!((back - (8.0 + 1.0) / 2.0 - 10.0).abs() < 1e-9, "{back}");
        // Above the first row's centres and below the last's: clamped.
        let zenith = m.radiance(&Vector3::new(1e-9, 0.0, 1.0), 0.0);
        assert!((1.0..=8.0).contains(&zenith), "{zenith}");
        let nadir = m.radiance(&Vector3::new(1e-9, 0.0, -1.0), 0.0);
        assert!((31.0..=38.0).contains(&nadir), "{nadir}");
        assert!(m.radiance(&Vector3::zeros(), 0.0).abs() < f64::MIN_POSITIVE);
    }

    #[test]
    fn bad_maps_are_refused_naming_what() {
        let e = EnvironmentMap::from_luminance(2, 2, vec![1.0; 3]).expect_err("short");
        assert!(e.to_string().contains("size"), "{e}");
        let e = EnvironmentMap::from_luminance(2, 2, vec![1.0, f32::NAN, 1.0, 1.0])
            .expect_err("not finite");
        assert!(e.to_string().contains("pixel (1, 0)"), "{e}");
        let e = EnvironmentMap::from_luminance(2, 2, vec![0.0; 4]).expect_err("black");
        assert!(e.to_string().contains("black"), "{e}");
    }

    /// A simulation file whose map is 2 above the horizon and 0.5 below,
    /// beside it in a temporary folder: the path is taken from the file's
    /// folder, the sky's pixels see 2 and the ground's 0.5 (times the
    /// level), and the map's errors name it.
    #[test]
    fn a_simulation_file_renders_its_map() {
        use crate::sim::{Class, SimConfig, SimRender};
        let dir = std::env::temp_dir().join(format!("rigview-env-sim-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let (w, h) = (64u32, 32u32);
        let map = image::Rgb32FImage::from_fn(w, h, |_, y| {
            let v = if y < h / 2 { 2.0 } else { 0.5 };
            image::Rgb([v, v, v])
        });
        map.save(dir.join("map.hdr")).expect("write the map");
        let text = |scene: &str| {
            format!(
                "format: rigview-sim\nversion: 1\nscale: 0.1\nsupersample: 1\n\
                 sensor: {{vignetting: 0.0}}\nscene:\n  ground: {{mat: null}}\n{scene}"
            )
        };
        let good = text("  environment: {file: map.hdr, level: 3.0}\n");
        let config = SimConfig::parse(&good, "map.sim.yaml", &dir).expect("parses");
        let file = &config.scene.environment.as_ref().expect("a map").file;
        assert_eq!(file, &dir.join("map.hdr"));
        let render = SimRender::new(&config).expect("renders");
        let info = &render.cameras()[0];
        let light = render.irradiance(0, 0.0).expect("irradiance");
        let (mut sky, mut ground) = (Vec::new(), Vec::new());
        for y in 0..info.height {
            for x in 0..info.width {
                let v = f64::from(light[y * info.width + x]);
                match render.class(0, x, y) {
                    Some(Class::Sky) => sky.push(v),
                    Some(Class::Ground) => ground.push(v),
                    _ => {}
                }
            }
        }
        assert!(!sky.is_empty() && !ground.is_empty());
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let ratio = median(&mut sky) / median(&mut ground);
        assert!((ratio - 4.0).abs() < 0.05, "sky / ground {ratio}");

        // Obstacles and a map together are refused, naming the field; a
        // missing map names its file.
        let both = text(
            "  environment: {file: map.hdr}\n  obstacles:\n  - {kind: wall, centre_m: [5.0, 0.0], size_m: [1.0, 1.0, 1.0]}\n",
        );
        let e = SimConfig::parse(&both, "both.sim.yaml", &dir).expect_err("obstacles");
        assert!(e.to_string().contains("scene.obstacles"), "{e}");
        let missing = text("  environment: {file: nowhere.hdr}\n");
        let config = SimConfig::parse(&missing, "missing.sim.yaml", &dir).expect("parses");
        let e = SimRender::new(&config).expect_err("no map");
        assert!(e.to_string().contains("nowhere.hdr"), "{e}");
        let level = text("  environment: {file: map.hdr, level: -1.0}\n");
        let e = SimConfig::parse(&level, "level.sim.yaml", &dir).expect_err("level");
        assert!(e.to_string().contains("scene.environment.level"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn files_that_are_not_radiance_maps_are_refused_naming_the_file() {
        let dir = std::env::temp_dir().join(format!("rigview-env-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let missing = dir.join("missing.hdr");
        let e = EnvironmentMap::load(&missing).expect_err("missing");
        assert!(e.to_string().contains("missing.hdr"), "{e}");
        let png = dir.join("grey.png");
        image::GrayImage::from_pixel(4, 2, image::Luma([128]))
            .save(&png)
            .expect("png");
        let e = EnvironmentMap::load(&png).expect_err("8-bit");
        assert!(
            e.to_string().contains("grey.png") && e.to_string().contains("radiance map"),
            "{e}"
        );
        let junk = dir.join("junk.hdr");
        std::fs::write(&junk, b"#?RADIANCE\nnot a map").expect("junk");
        let e = EnvironmentMap::load(&junk).expect_err("junk");
        assert!(e.to_string().contains("junk.hdr"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
