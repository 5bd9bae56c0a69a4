use std::path::{Path, PathBuf};
use std::time::Duration;

use rigview_core::exposure::{ExposureSetting, PixelFormat};
use rigview_core::source::FrameSource;

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
            layout: Layout::default(),
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
    let options = BracketOptions::new(setting(1900.0, 0.0), BracketMode::Nearest);
    let mut src = BracketSource::open(dir.path(), &names(), &options).unwrap();
    let set = src.next_set(Duration::ZERO).unwrap().unwrap();
    let f = set.frames[0].as_ref().unwrap();
    assert!(
        (f.meta.taken.shutter_us - 2000.0).abs() < 1e-9,
        "{:?}",
        f.meta.taken
    );
    assert!(src.is_finished());
}

/// A sequence of two moments at `t0` and `t1` (s), one image each of the
/// two cameras.
fn two_moments(dir: &Path, t0: f64, t1: f64) {
    let m: String = [(0, t0), (1, t1)]
        .iter()
        .flat_map(|&(k, t)| ["front", "left"].map(|c| format!("{c},{k},{t},1000,0,front/a.png\n")))
        .collect();
    write(dir, &format!("{HEADER}{m}"), &["front/a.png"]);
}

#[test]
fn the_streams_report_the_rate_the_sets_are_served_at() {
    let dir = tempfile::tempdir().unwrap();
    two_moments(dir.path(), 0.0, 0.05);
    let options = BracketOptions::new(setting(1000.0, 0.0), BracketMode::Nearest);
    let mut src = BracketSource::open(dir.path(), &names(), &options).unwrap();
    src.next_set(Duration::ZERO).unwrap().unwrap();
    assert!(src.health().iter().all(|h| h.fps.abs() < 1e-12));
    std::thread::sleep(Duration::from_millis(20));
    src.next_set(Duration::ZERO).unwrap().unwrap();
    // Two sets at least 20 ms apart: a positive rate below 50 per second.
    let health = src.health();
    assert!(
        health
            .iter()
            .all(|h| h.fps > 0.0 && h.fps <= 50.0 && h.completed == 2),
        "{health:?}"
    );
}

#[test]
fn in_real_time_each_moment_is_served_at_its_time() {
    let dir = tempfile::tempdir().unwrap();
    two_moments(dir.path(), 5.0, 5.06);
    let options = BracketOptions {
        realtime: true,
        ..BracketOptions::new(setting(1000.0, 0.0), BracketMode::Nearest)
    };
    let mut src = BracketSource::open(dir.path(), &names(), &options).unwrap();
    let start = std::time::Instant::now();
    // The first moment at once (its time is the sequence's start), the
    // second 60 ms later: a 1 ms wait gives nothing.
    assert!(src.next_set(Duration::from_millis(1)).unwrap().is_some());
    assert!(src.next_set(Duration::from_millis(1)).unwrap().is_none());
    assert!(!src.is_finished());
    assert!(src.next_set(Duration::from_secs(5)).unwrap().is_some());
    assert!(start.elapsed() >= Duration::from_millis(59));
    assert!(src.is_finished());
    // Not in real time, both at once.
    let options = BracketOptions::new(setting(1000.0, 0.0), BracketMode::Nearest);
    let mut src = BracketSource::open(dir.path(), &names(), &options).unwrap();
    assert!(src.next_set(Duration::ZERO).unwrap().is_some());
    assert!(src.next_set(Duration::ZERO).unwrap().is_some());
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
        e.contains("brackets.csv line 3") && e.contains("gone.png") && e.contains("does not exist"),
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

/// Writes a 16-bit grey PNG of `w`×`h` with value `f(x, y)`.
fn png16(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> u16) {
    image::ImageBuffer::<image::Luma<u16>, _>::from_fn(w, h, |x, y| image::Luma([f(x, y)]))
        .save(path)
        .unwrap();
}

#[test]
fn patterns_and_bits_come_from_comments_and_columns() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("front")).unwrap();
    png16(&dir.path().join("front/a.png"), 8, 6, |x, y| {
        (x * 500 + y) as u16
    });
    let manifest = format!(
        "# pattern: RGGB\n# bits: 12\n{}pattern,bits\nfront,0,0,1000,0,front/a.png,,\nleft,0,0,1000,0,front/a.png,mono,16\nleft,0,0,2000,0,front/a.png,gbrg,\n",
        HEADER.trim_end().to_owned() + ","
    );
    std::fs::write(dir.path().join(MANIFEST), manifest).unwrap();
    let m = read_manifest(dir.path(), &names()).unwrap();
    let front = &m.moments[0].cameras[0][0];
    let d = read_image(&m, front).unwrap();
    assert_eq!(
        (d.format, d.width, d.height),
        (PixelFormat::BayerRg12, 8, 6)
    );
    // The samples as they are: 3500 at (7, 0).
    assert_eq!(u16::from_le_bytes([d.data[14], d.data[15]]), 3500);
    let left = &m.moments[0].cameras[1];
    assert_eq!(
        read_image(&m, &left[0]).unwrap().format,
        PixelFormat::Mono16
    );
    assert_eq!(
        read_image(&m, &left[1]).unwrap().format,
        PixelFormat::BayerGb12
    );
}

/// The error of reading every image of a one-camera sequence whose
/// manifest is `lines` after the header (with the optional columns).
fn image_error(lines: &str, images: &[(&str, u32, u32, u16)]) -> String {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("front")).unwrap();
    for &(f, w, h, v) in images {
        png16(&dir.path().join(f), w, h, |_, _| v);
    }
    let header = "camera,moment,time_s,exposure_us,gain_db,file,pattern,bits\n";
    std::fs::write(dir.path().join(MANIFEST), format!("{header}{lines}")).unwrap();
    let names = vec!["front".to_owned()];
    let e = read_manifest(dir.path(), &names).and_then(|m| {
        for i in &m.moments[0].cameras[0] {
            read_image(&m, i)?;
        }
        Ok(())
    });
    format!("{:#}", e.unwrap_err())
}

#[test]
fn a_pattern_or_a_depth_that_does_not_fit_names_the_line() {
    // A mosaic of odd width.
    let e = image_error(
        "front,0,0,1000,0,front/a.png,RGGB,16\nfront,0,0,2000,0,front/b.png,BGGR,16\n",
        &[("front/a.png", 8, 6, 10), ("front/b.png", 7, 6, 10)],
    );
    assert!(
        e.contains("brackets.csv line 3")
            && e.contains("pattern BGGR")
            && e.contains("7×6")
            && e.contains("even width and height"),
        "{e}"
    );
    // 12 bits declared, a value above 4095.
    let e = image_error(
        "front,0,0,1000,0,front/a.png,mono,12\n",
        &[("front/a.png", 8, 6, 4096)],
    );
    assert!(
        e.contains("line 2") && e.contains("bits 12") && e.contains("4096"),
        "{e}"
    );
    // 8 bits declared on a 16-bit PNG.
    let e = image_error(
        "front,0,0,1000,0,front/a.png,,8\n",
        &[("front/a.png", 8, 6, 1)],
    );
    assert!(e.contains("line 2") && e.contains("16-bit PNG"), "{e}");
    // A pattern and a depth that are none.
    let e = image_error(
        "front,0,0,1000,0,front/a.png,RGBG,\n",
        &[("front/a.png", 8, 6, 1)],
    );
    assert!(
        e.contains("line 2") && e.contains("pattern \"RGBG\"") && e.contains("RGGB"),
        "{e}"
    );
    let e = image_error(
        "front,0,0,1000,0,front/a.png,,10\n",
        &[("front/a.png", 8, 6, 1)],
    );
    assert!(e.contains("line 2") && e.contains("8, 12 or 16"), "{e}");
}

#[test]
fn a_writer_keeps_mosaics_and_their_depth() {
    let dir = tempfile::tempdir().unwrap();
    let names = names();
    let mut w = BracketWriter::create(dir.path(), None, &names, "test").unwrap();
    let wide: Vec<u8> = (0..8 * 6u16).flat_map(|v| (v * 80).to_le_bytes()).collect();
    let narrow: Vec<u8> = (0..8 * 6u8).collect();
    let frames = [
        BracketFrame {
            camera: 0,
            setting: setting(1000.0, 0.0),
            format: PixelFormat::BayerGr12,
            width: 8,
            height: 6,
            data: &wide,
        },
        BracketFrame {
            camera: 1,
            setting: setting(1000.0, 0.0),
            format: PixelFormat::BayerBg8,
            width: 8,
            height: 6,
            data: &narrow,
        },
    ];
    w.write_moment(0.0, &frames).unwrap();
    let m = read_manifest(dir.path(), &names).unwrap();
    for (cam, f) in frames.iter().enumerate() {
        let d = read_image(&m, &m.moments[0].cameras[cam][0]).unwrap();
        assert_eq!((d.format, d.data.as_slice()), (f.format, f.data));
    }
    // RGB is refused, naming the format.
    let rgb = vec![0u8; 8 * 6 * 3];
    let e = w
        .write_moment(
            0.1,
            &[BracketFrame {
                format: PixelFormat::Rgb8,
                data: &rgb,
                ..frames[0]
            }],
        )
        .unwrap_err();
    assert!(format!("{e:#}").contains("RGB8"), "{e:#}");
}

#[test]
fn emulate_mode_answers_any_exposure_within_the_brackets_widened() {
    // One camera, 12-bit, a linear ramp: value = x · E with x from 0.01 to
    // 1 DN/µs; brackets at 500, 1000 and 2000 µs.
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("front")).unwrap();
    let x = |px: u32, py: u32| 0.01 + 0.99 * f64::from(py * 64 + px) / (64.0 * 48.0);
    let mut lines = String::from(
        "# response: linear\ncamera,moment,time_s,exposure_us,gain_db,file,pattern,bits\n",
    );
    for (k, e) in [500.0, 1000.0, 2000.0].iter().enumerate() {
        let f = format!("front/{k}.png");
        png16(&dir.path().join(&f), 64, 48, |px, py| {
            (x(px, py) * e).round().min(4095.0) as u16
        });
        lines += &format!("front,0,0,{e},0,{f},RGGB,12\n");
    }
    std::fs::write(dir.path().join(MANIFEST), lines).unwrap();
    let names = vec!["front".to_owned()];
    let open = |mode| {
        BracketSource::open(
            dir.path(),
            &names,
            &BracketOptions::new(setting(1400.0, 0.0), mode),
        )
        .unwrap()
    };
    let mut src = open(BracketMode::Emulate);
    let info = &src.cameras()[0];
    assert_eq!(info.levels, None);
    assert_eq!(info.format, PixelFormat::BayerRg12);
    assert_eq!(
        (info.range.shutter_min_us, info.range.shutter_max_us),
        (250.0, 4000.0)
    );
    let set = src.next_set(Duration::ZERO).unwrap().unwrap();
    let f = set.frames[0].as_ref().unwrap();
    assert_eq!(f.meta.taken, setting(1400.0, 0.0));
    // The mean over the frame is x̄ · 1400 within the noise.
    let px: Vec<f64> = f
        .data
        .chunks_exact(2)
        .map(|c| f64::from(u16::from_le_bytes([c[0], c[1]])))
        .collect();
    let mean = px.iter().sum::<f64>() / px.len() as f64;
    let want = (0..48)
        .flat_map(|py| (0..64).map(move |px| x(px, py) * 1400.0))
        .sum::<f64>()
        / px.len() as f64;
    assert!((mean / want - 1.0).abs() < 0.005, "{mean} for {want}");
    // Beyond the span widened by 1 EV, the level is clamped.
    let far = BracketSource::open(
        dir.path(),
        &names,
        &BracketOptions::new(setting(100_000.0, 6.0), BracketMode::Emulate),
    )
    .unwrap()
    .next_set(Duration::ZERO)
    .unwrap()
    .unwrap();
    let taken = far.frames[0].as_ref().unwrap().meta.taken;
    assert!((taken.exposure() - 4000.0).abs() < 1e-6, "{taken:?}");
    // Nearest mode gives the 1000 µs bracket and its levels.
    let mut near = open(BracketMode::Nearest);
    assert_eq!(near.cameras()[0].levels, Some(vec![500.0, 1000.0, 2000.0]));
    let set = near.next_set(Duration::ZERO).unwrap().unwrap();
    assert_eq!(
        set.frames[0].as_ref().unwrap().meta.taken,
        setting(1000.0, 0.0)
    );
}

/// Writes one camera's bracket of 8-bit images of a display gamma (`z =
/// 255 (v/255)^(1/2.2)` of the linear value `v`) over a scene spanning
/// three decades, with `comment` before the header; a folder for
/// [`check_emulation`].
fn gamma_bracket(dir: &Path, comment: &str) {
    std::fs::create_dir_all(dir.join("front")).unwrap();
    let (w, h) = (160u32, 120u32);
    let x = |px: u32, py: u32| 1e-3 * 10f64.powf(3.0 * f64::from(py * w + px) / f64::from(w * h));
    let mut lines = format!("{comment}camera,moment,time_s,exposure_us,gain_db,file\n");
    for (k, e) in [100.0, 200.0, 400.0, 800.0, 1600.0, 3200.0]
        .iter()
        .enumerate()
    {
        let f = format!("front/{k}.png");
        image::GrayImage::from_fn(w, h, |px, py| {
            let v = (x(px, py) * e).min(255.0);
            image::Luma([(255.0 * (v / 255.0).powf(1.0 / 2.2)).round() as u8])
        })
        .save(dir.join(&f))
        .unwrap();
        lines += &format!("front,0,0,{e},0,{f}\n");
    }
    std::fs::write(dir.join(MANIFEST), lines).unwrap();
}

#[test]
fn an_8_bit_sequence_without_a_response_has_it_recovered() {
    let options = CheckOptions {
        moments: None,
        seed: 1,
    };
    let recovered = tempfile::tempdir().unwrap();
    gamma_bracket(recovered.path(), "");
    let r = check_emulation(recovered.path(), &options).unwrap();
    let linear = tempfile::tempdir().unwrap();
    gamma_bracket(linear.path(), "# response: linear\n");
    let l = check_emulation(linear.path(), &options).unwrap();
    println!("recovered {:?}\nlinear {:?}", r.all, l.all);
    assert_eq!(r.levels.len(), 4);
    // The recovered curve is the display gamma's; declared linear, none.
    let [(name, Some(inverse))] = &r.responses[..] else {
        panic!("responses {:?}", r.responses.len());
    };
    assert_eq!(name, "front");
    let g = CheckReport::power_of(inverse).unwrap();
    assert!((g - 2.2).abs() < 0.15, "exponent {g}");
    assert!(matches!(&l.responses[..], [(_, None)]));
    assert!(r.all.median_ev <= 0.05, "{:?}", r.all);
    // Taken as linear, the gamma curve's images are emulated worse.
    assert!(
        l.all.median_ev > 2.0 * r.all.median_ev,
        "{:?} {:?}",
        l.all,
        r.all
    );
}

/// The goal needs every level, not only the median over every image: on a
/// real 8-bit bracket (Debevec's Memorial Church, 16 levels) nine short
/// levels on the black pedestal were emulated to the code (0.0003 EV) and
/// outnumbered the five long ones that missed (up to 0.19 EV).
#[test]
fn the_emulation_goal_holds_at_every_level() {
    let level = |l: f64, m: f64, noisy: f64| LevelFigures {
        level: Some(l),
        images: 1,
        samples: 100,
        median_ev: m,
        median_ev_noisy: noisy,
        psnr_db: 30.0,
        psnr_db_noisy: 30.0,
    };
    let mut report = CheckReport {
        moments: 1,
        levels: vec![
            level(1000.0, 0.0003, 0.0003),
            level(2000.0, 0.0003, 0.0003),
            level(4000.0, 0.04, 0.05),
        ],
        all: LevelFigures {
            level: None,
            ..level(0.0, 0.0003, 0.0003)
        },
        responses: Vec::new(),
    };
    assert!(report.meets(0.05));
    assert!(report.levels_over(0.05).is_empty());
    report.levels.push(level(8000.0, 0.02, 0.19));
    report.levels.push(level(16000.0, 0.09, 0.13));
    assert!(!report.meets(0.05));
    assert_eq!(report.levels_over(0.05), vec![8000.0, 16000.0]);
    report.levels[4].median_ev_noisy = f64::NAN;
    assert_eq!(report.levels_over(0.05), vec![8000.0, 16000.0]);
}

/// The power curve nearest a response: 1 for a linear one, 2.2 for a
/// display gamma, none without codes above zero.
#[test]
fn the_nearest_power_curve_of_a_response() {
    let power = |g: f64| -> Vec<f32> {
        (0..256)
            .map(|z| (255.0 * (f64::from(z) / 255.0).powf(g)) as f32)
            .collect()
    };
    for g in [1.0, 2.2] {
        let got = CheckReport::power_of(&power(g)).unwrap();
        assert!((got - g).abs() < 1e-3, "{g}: {got}");
    }
    assert_eq!(CheckReport::power_of(&[0.0; 256]), None);
    assert_eq!(CheckReport::power_of(&[1.0; 10]), None);
}
