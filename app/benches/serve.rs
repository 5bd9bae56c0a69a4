#![allow(clippy::unwrap_used, clippy::expect_used)]
//! What the live remote view costs per published set at its defaults:
//! four 1288×964 camera frames and a 1000×1000 composed view (grey for a
//! grey rig, RGB for a colour one) shrunk to half size and JPEG-encoded
//! (quality 80): the work of the
//! publishing thread (`rigview::serve`); at 10 sets a second its share of
//! a core is ten times the time of one.
//!
//! - `rigview_mono8` / `rigview_rgb8`: `serve::preview::shrink` (2 × 2
//!   boxes) and `serve::preview::jpeg` for each camera, then the view.
//! - `image_resize_mono8` (peer): the `image` crate's `resize` (triangle
//!   filter) to half size and its JPEG encoder.
//!
//! The pictures: the real surround-nz frames scaled to 1288×964 (grey for
//! Mono8), the view the front frame at 1000×1000. Results:
//! `BENCHMARKS.md`.

use std::hint::black_box;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use image::imageops::FilterType;
use rigview::serve::preview::{self, Small};
use rigview_core::image::PixelFormat;
use rigview_core::source::{Frame, FrameMeta};

fn frame(k: usize, format: PixelFormat, w: usize, h: usize, data: Vec<u8>) -> Frame {
    Frame::new(FrameMeta::still(k, format, w, h), Arc::from(data)).unwrap()
}

fn serve(c: &mut Criterion) {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz");
    let (w, h) = (1288u32, 964u32);
    let rgb: Vec<image::RgbImage> = ["front", "left", "back", "right"]
        .iter()
        .map(|n| {
            image::open(data.join(format!("{n}.png")))
                .unwrap()
                .resize_exact(w, h, FilterType::Triangle)
                .to_rgb8()
        })
        .collect();
    let mono: Vec<Frame> = rgb
        .iter()
        .enumerate()
        .map(|(k, im)| {
            let grey = image::DynamicImage::ImageRgb8(im.clone()).to_luma8();
            frame(
                k,
                PixelFormat::Mono8,
                w as usize,
                h as usize,
                grey.into_raw(),
            )
        })
        .collect();
    let colour: Vec<Frame> = rgb
        .iter()
        .enumerate()
        .map(|(k, im)| {
            frame(
                k,
                PixelFormat::Rgb8,
                w as usize,
                h as usize,
                im.as_raw().clone(),
            )
        })
        .collect();
    let view_image = image::DynamicImage::ImageRgb8(rgb[0].clone())
        .resize_exact(1000, 1000, FilterType::Triangle)
        .to_rgb8();
    // The view of a grey rig is grey, of a colour rig colour.
    let grey_view = Small {
        width: 1000,
        height: 1000,
        channels: 1,
        data: image::DynamicImage::ImageRgb8(view_image.clone())
            .to_luma8()
            .into_raw(),
    };
    let view = Small {
        width: 1000,
        height: 1000,
        channels: 3,
        data: view_image.into_raw(),
    };
    let publish = |frames: &[Frame], view: &Small| {
        let mut bytes = 0;
        for f in frames {
            bytes += preview::jpeg(&preview::shrink(f, 2).unwrap(), 80)
                .unwrap()
                .len();
        }
        bytes
            + preview::jpeg(
                &preview::shrink_picture(&view.data, (view.width, view.height), view.channels, 2),
                80,
            )
            .unwrap()
            .len()
    };
    eprintln!(
        "serve: a Mono8 set publishes {} KB, an RGB8 set {} KB",
        publish(&mono, &grey_view) / 1024,
        publish(&colour, &view) / 1024
    );
    let mut group = c.benchmark_group("serve_set_4x1288x964_and_view");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5));
    group.bench_function("rigview_mono8", |b| {
        b.iter(|| black_box(publish(&mono, &grey_view)));
    });
    group.bench_function("rigview_rgb8", |b| {
        b.iter(|| black_box(publish(&colour, &view)));
    });
    group.bench_function("image_resize_mono8", |b| {
        b.iter(|| {
            let mut bytes = 0;
            for f in &mono {
                let im = image::GrayImage::from_raw(w, h, f.data.to_vec()).unwrap();
                let half = image::imageops::resize(&im, w / 2, h / 2, FilterType::Triangle);
                let small = Small {
                    width: (w / 2) as usize,
                    height: (h / 2) as usize,
                    channels: 1,
                    data: half.into_raw(),
                };
                bytes += preview::jpeg_with_image(&small, 80).unwrap().len();
            }
            let half = image::imageops::resize(
                &image::GrayImage::from_raw(1000, 1000, grey_view.data.clone()).unwrap(),
                500,
                500,
                FilterType::Triangle,
            );
            let half = Small {
                width: 500,
                height: 500,
                channels: 1,
                data: half.into_raw(),
            };
            black_box(bytes + preview::jpeg_with_image(&half, 80).unwrap().len());
        });
    });
    group.finish();
}

criterion_group!(benches, serve);
criterion_main!(benches);
