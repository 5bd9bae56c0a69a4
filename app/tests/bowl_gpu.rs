//! The bowl drawn on the GPU agrees with the bowl composed on the CPU:
//! the real surround-nz frames from three viewpoints, drawn by the
//! window's renderer ([`rigview::gui::bowl_gl`]) in a headless OpenGL
//! context (Mesa's EGL without a display, software rendering), against
//! [`BowlView`]'s maps through the composer with the vehicle painted over,
//! in each blend mode and with the display's seam gains.
//! Away from edges (where a camera's coverage, the vehicle or the rim
//! begins) the two differ by at most 2 grey levels on the mean.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;

use rigview::commands::surround;
use rigview::gui::bowl_gl::{headless_context, BowlGl, Shot, TextureFrame};
use rigview_core::bowl::{BowlSpec, BowlView, SurfaceMesh, VehicleTriangles, Viewpoint};
use rigview_core::surround::{BlendMode, Canvas, CanvasSpec, Composer};

fn data() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz")
}

/// Per pixel, whether it lies within `band` pixels of an edge of the
/// picture's structure: where the set of cameras that show it, or the
/// vehicle's cover, changes.
fn near_edges(view: &BowlView, mode: BlendMode, band: usize) -> Vec<bool> {
    let (w, h) = view.mosaic().size();
    let cameras = view.mosaic().layers().len();
    let signature: Vec<u32> = (0..w * h)
        .map(|i| {
            let (c, r) = (i % w, i / w);
            let mut s = 0u32;
            for k in 0..cameras {
                if view.mosaic().weight(k, mode, c, r) > 0 {
                    s |= 1 << k;
                }
            }
            if view.vehicle_at(c, r).is_some() {
                s |= 1 << 8;
            }
            s
        })
        .collect();
    let mut out = vec![false; w * h];
    for r in 0..h {
        for c in 0..w {
            let me = signature[r * w + c];
            let (r0, r1) = (r.saturating_sub(band), (r + band).min(h - 1));
            let (c0, c1) = (c.saturating_sub(band), (c + band).min(w - 1));
            'window: for rr in r0..=r1 {
                for cc in c0..=c1 {
                    if signature[rr * w + cc] != me {
                        out[r * w + c] = true;
                        break 'window;
                    }
                }
            }
        }
    }
    out
}

#[test]
fn the_gpus_bowl_agrees_with_the_cpus_away_from_edges() {
    let (rig, images) = surround::load(
        &data(),
        &["front", "left", "back", "right"]
            .iter()
            .map(|n| data().join(format!("{n}.png")).display().to_string())
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let frames = surround::frames(&images).unwrap();
    let spec = BowlSpec {
        size_px: [1280, 800],
        ..BowlSpec::around(&CanvasSpec::around_car_16x12(25.0))
    };
    let gl = headless_context().unwrap();
    let mut renderer = BowlGl::new(&gl).unwrap();
    let textures: Vec<TextureFrame<'_>> = images.iter().map(TextureFrame::rgb).collect();
    renderer.upload(&gl, &textures).unwrap();
    let [w, h] = spec.size_px;
    let mut geometry = None;
    // The display's seam gains too (the fourth viewpoint).
    let gains = [1.3f32, 0.8, 1.1, 0.9];
    for (name, mode, gained) in [
        ("top", BlendMode::Linear, false),
        ("behind-left", BlendMode::Linear, false),
        ("left", BlendMode::Seams, false),
        ("behind-right", BlendMode::Alpha, true),
    ] {
        let seam = if gained { gains } else { [1.0; 4] };
        let viewpoint = Viewpoint::preset(name).unwrap();
        let view = BowlView::build(&rig, &spec, &viewpoint).unwrap();
        if geometry.is_none() {
            let mesh = SurfaceMesh::build(&rig, &spec, view.plan()).unwrap();
            renderer.set_geometry(&gl, &mesh, &VehicleTriangles::of(&spec, None));
            geometry = Some(mesh.vertices.len());
        }
        let mut cpu = Canvas::new(w, h, 3);
        Composer::new()
            .compose_with_gains(view.mosaic(), &frames, mode, Some(&seam), &mut cpu)
            .unwrap();
        view.paint_vehicle(&mut cpu).unwrap();
        renderer
            .draw(
                &gl,
                &Shot {
                    camera: viewpoint.camera(w, h),
                    size: (w, h),
                    gains: seam.iter().map(|&g| [1.0, g]).collect(),
                    mode,
                },
            )
            .unwrap();
        let (gw, gh, gpu) = renderer.read_rgb(&gl).unwrap();
        assert_eq!((gw, gh), (w, h));
        let edges = near_edges(&view, mode, 2);
        let (mut sum, mut n, mut lit) = (0u64, 0u64, 0u64);
        for (i, &edge) in edges.iter().enumerate() {
            if edge {
                continue;
            }
            for ch in 0..3 {
                let (a, b) = (cpu.data[3 * i + ch], gpu[3 * i + ch]);
                sum += u64::from(a.abs_diff(b));
                n += 1;
                lit += u64::from(a > 8);
            }
        }
        let mad = sum as f64 / n as f64;
        let compared = n as f64 / (3 * w * h) as f64;
        eprintln!(
            "{name} ({}): mean |CPU − GPU| {mad:.3} grey levels over {:.1} % of the picture ({:.1} % of it lit)",
            mode.name(),
            100.0 * compared,
            100.0 * lit as f64 / n as f64
        );
        if std::env::var_os("RIGVIEW_SAVE_BOWLS").is_some() {
            let save = |data: Vec<u8>, what: &str| {
                image::RgbImage::from_raw(w as u32, h as u32, data)
                    .unwrap()
                    .save(std::env::temp_dir().join(format!("bowl-{name}-{what}.png")))
                    .unwrap();
            };
            save(cpu.data.clone(), "cpu");
            save(gpu.clone(), "gpu");
        }
        assert!(compared > 0.8, "{name}: only {compared} compared");
        assert!(
            lit as f64 > 0.5 * n as f64,
            "{name}: the picture is mostly dark"
        );
        assert!(mad <= 2.0, "{name}: mean difference {mad}");
    }
    renderer.destroy(&gl);
}
