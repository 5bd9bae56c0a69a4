use super::*;

/// A meter to `side×side` metered pixels.
fn square_meter(side: usize) -> Meter {
    Meter::new(MeteringConfig {
        target_width: side,
        target_height: side,
    })
    .unwrap()
}

/// A 12×12 frame of `format` (Bayer: 24×24 sensor pixels, 12×12 quads)
/// at grey level `base` with each sample of `hot` at its own level.
fn frame_with(format: PixelFormat, base: u8, hot: &[((usize, usize), u8)]) -> Vec<u8> {
    let side = if format.is_bayer() { 24 } else { 12 };
    let bpp = format.bytes_per_pixel();
    let mut data = vec![0u8; side * side * bpp];
    let put = |data: &mut [u8], x: usize, y: usize, v: u8| {
        let i = (y * side + x) * bpp;
        match format {
            PixelFormat::Mono12 => {
                let w = u16::from(v) * 16 + u16::from(v) / 16;
                data[i..i + 2].copy_from_slice(&w.to_le_bytes());
            }
            PixelFormat::Mono16 => {
                data[i..i + 2].copy_from_slice(&(u16::from(v) * 257).to_le_bytes());
            }
            _ => data[i..i + bpp].fill(v),
        }
    };
    for y in 0..side {
        for x in 0..side {
            put(&mut data, x, y, base);
        }
    }
    for &((x, y), value) in hot {
        if format.is_bayer() {
            // The whole quad.
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                put(&mut data, 2 * x + dx, 2 * y + dy, value);
            }
        } else {
            put(&mut data, x, y, value);
        }
    }
    data
}

#[test]
fn metered_blocks_carry_the_fraction_of_their_saturated_samples() {
    let meter = square_meter(3);
    for format in [
        PixelFormat::Mono8,
        PixelFormat::Mono12,
        PixelFormat::Mono16,
        PixelFormat::Rgb8,
        PixelFormat::BayerRg8,
    ] {
        let side = if format.is_bayer() { 24 } else { 12 };
        // Block (0, 0) gets three saturated samples, block (2, 1) one
        // just below the level (249/255 < 0.98) and one at it (250).
        let hot = [
            ((0, 0), 255),
            ((3, 1), 255),
            ((2, 3), 255),
            ((9, 5), 249),
            ((10, 6), 250),
        ];
        let data = frame_with(format, 100, &hot);
        let frame = FrameView::new(format, side, side, &data).unwrap();
        let m = meter.meter(&frame, None).unwrap();
        assert_eq!((m.width(), m.height()), (3, 3), "{format:?}");
        let plane = m.saturated_samples().unwrap();
        let want = [3.0 / 16.0, 0.0, 0.0, 0.0, 0.0, 1.0 / 16.0, 0.0, 0.0, 0.0];
        assert_eq!(plane, want, "{format:?}");
        // Nothing saturated: no plane; one sample per metered pixel: no
        // plane (the pixel itself says it).
        let plain = frame_with(format, 100, &[]);
        let frame = FrameView::new(format, side, side, &plain).unwrap();
        assert!(meter
            .meter(&frame, None)
            .unwrap()
            .saturated_samples()
            .is_none());
        let one = square_meter(12);
        let frame = FrameView::new(format, side, side, &data).unwrap();
        assert!(one
            .meter(&frame, None)
            .unwrap()
            .saturated_samples()
            .is_none());
    }
}

fn frame_and_mask(format: PixelFormat) -> (Vec<u8>, RoiMask, usize, usize) {
    let (w, h) = (644, 482);
    let bpp = format.bytes_per_pixel();
    let data: Vec<u8> = (0..w * h * bpp).map(|i| ((i * 7919) % 251) as u8).collect();
    // A disc of ground, as a fisheye's ground mask looks.
    let mask: Vec<u8> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 - 300.0, (i / w) as f64 - 300.0);
            u8::from(x * x + y * y < 200.0 * 200.0)
        })
        .collect();
    (data, RoiMask::new(w, h, mask).unwrap(), w, h)
}

#[test]
fn a_prepared_mask_meters_exactly_as_the_mask_itself() {
    let meter = Meter::new(MeteringConfig::default()).unwrap();
    for format in [PixelFormat::Mono8, PixelFormat::Rgb8, PixelFormat::BayerRg8] {
        let (data, mask, w, h) = frame_and_mask(format);
        let frame = FrameView::new(format, w, h, &data).unwrap();
        let direct = meter.meter(&frame, Some(&mask)).unwrap();
        let prepared = meter.prepare(&mask, format).unwrap();
        let via = meter.meter_prepared(&frame, &prepared).unwrap();
        assert_eq!(direct.luma(), via.luma(), "{format:?}");
        assert_eq!(direct.weight(), via.weight(), "{format:?}");
        assert_eq!(direct.stats(), via.stats(), "{format:?}");
        let covered = via.weight().unwrap().iter().filter(|&&v| v > 0.0).count();
        assert!(
            covered > 100 && covered < via.width() * via.height() / 2,
            "{covered}"
        );
    }
}

#[test]
fn a_prepared_mask_refuses_another_frame_size() {
    let meter = Meter::new(MeteringConfig::default()).unwrap();
    let (data, mask, w, h) = frame_and_mask(PixelFormat::Mono8);
    let prepared = meter.prepare(&mask, PixelFormat::Mono8).unwrap();
    let smaller = FrameView::new(PixelFormat::Mono8, w - 4, h, &data[..(w - 4) * h]).unwrap();
    assert!(matches!(
        meter.meter_prepared(&smaller, &prepared),
        Err(Error::SizeMismatch { .. })
    ));
    // A Bayer frame of the same size meters on quads: refused too.
    let (bayer, _, _, _) = frame_and_mask(PixelFormat::BayerRg8);
    let frame = FrameView::new(PixelFormat::BayerRg8, w, h, &bayer).unwrap();
    assert!(meter.meter_prepared(&frame, &prepared).is_err());
}

#[test]
fn a_16_bit_mosaic_meters_as_the_8_bit_one_of_the_same_light() {
    // Samples v·257 in 16 bits are v/255 of full scale, as v in 8 bits:
    // the same luminance and the same saturation, block by block.
    let meter = square_meter(6);
    let side = 24;
    let narrow: Vec<u8> = (0..side * side)
        .map(|i| ((i * 7919 + 13) % 256) as u8)
        .collect();
    let wide: Vec<u8> = narrow
        .iter()
        .flat_map(|&v| (u16::from(v) * 257).to_le_bytes())
        .collect();
    for (w8, w16) in [
        (PixelFormat::BayerRg8, PixelFormat::BayerRg16),
        (PixelFormat::BayerGb8, PixelFormat::BayerGb16),
    ] {
        let a = meter
            .meter(&FrameView::new(w8, side, side, &narrow).unwrap(), None)
            .unwrap();
        let b = meter
            .meter(&FrameView::new(w16, side, side, &wide).unwrap(), None)
            .unwrap();
        for (x, y) in a.luma().iter().zip(b.luma()) {
            assert!((x - y).abs() < 1e-6, "{w16:?}: {x} {y}");
        }
        let (sa, sb) = (
            a.saturated_samples().unwrap(),
            b.saturated_samples().unwrap(),
        );
        assert!(sa.iter().any(|&v| v > 0.0));
        for (x, y) in sa.iter().zip(sb) {
            assert!((x - y).abs() < 1e-6, "{w16:?}: saturated {x} {y}");
        }
    }
}

#[test]
fn metering_one_sample_per_pixel_gives_the_luminance_of_luma_at() {
    // One metered pixel per pixel (or Bayer quad): the metering's
    // luminance and the frame's own agree exactly, in every format; and
    // `for_each_luma` reads what `luma_at` reads.
    let meter = square_meter(12);
    for format in PixelFormat::ALL {
        let side = if format.is_bayer() { 24 } else { 12 };
        let data: Vec<u8> = (0..side * side * format.bytes_per_pixel())
            .map(|i| ((i * 7919 + 13) % 256) as u8)
            .collect();
        let frame = FrameView::new(format, side, side, &data).unwrap();
        let m = meter.meter(&frame, None).unwrap();
        assert_eq!((m.width(), m.height()), (12, 12), "{format:?}");
        let step = if format.is_bayer() { 2 } else { 1 };
        for y in 0..12 {
            for x in 0..12 {
                let want = m.luma()[y * 12 + x];
                // Every pixel of a quad reads the quad.
                for (dx, dy) in [(0, 0), (step - 1, 0), (0, step - 1), (step - 1, step - 1)] {
                    let got = frame.luma_at(step * x + dx, step * y + dy);
                    assert_eq!(got.to_bits(), want.to_bits(), "{format:?} ({x}, {y})");
                }
            }
        }
        // Not all alike: the test reads different values.
        assert!(m.stats().histogram.iter().filter(|&&c| c > 0).count() > 20);
        // Read by index list, in a scattered order, the same bits.
        let pixels: Vec<u32> = (0..side * side)
            .map(|i| (i * 37 % (side * side)) as u32)
            .collect();
        let mut got = Vec::new();
        frame.for_each_luma(&pixels, |v| got.push(v.to_bits()));
        let want: Vec<u32> = pixels
            .iter()
            .map(|&p| {
                frame
                    .luma_at(p as usize % side, p as usize / side)
                    .to_bits()
            })
            .collect();
        assert_eq!(got, want, "{format:?}: for_each_luma");
        // The same frame with padded rows reads the same.
        let row = side * format.bytes_per_pixel();
        let padded: Vec<u8> = data
            .chunks_exact(row)
            .flat_map(|r| r.iter().copied().chain([0xa5; 5]))
            .collect();
        let strided = FrameView::with_stride(format, side, side, row + 5, &padded).unwrap();
        let mut got = Vec::new();
        strided.for_each_luma(&pixels, |v| got.push(v.to_bits()));
        assert_eq!(got, want, "{format:?}: for_each_luma, padded rows");
    }
}

/// A xorshift generator from `state` (not zero).
fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}

/// The one-pass metering of 8-bit frames (16-bit sums, 8-bit saturated
/// counts) gives exactly the values of the two-pass one it replaced for
/// blocks of up to 255 rows, on frames with saturated and dark samples, for
/// block sides from 1 to 8 and 16 (the powers of two take the halving
/// sums of RGB rows) and a width that leaves a remainder.
#[test]
fn one_pass_8bit_metering_equals_the_two_pass_sums() {
    let h = 61usize;
    let mut next = xorshift(0x2545_f491_4f6c_dd1d);
    // Rows of whole and of partial 32-column steps (the Mono8 4×4 kernel).
    let cases = [(PixelFormat::Mono8, 1, 203), (PixelFormat::Mono8, 1, 256)];
    // RGB8 too: whole and partial 32-pixel steps (the RGB8 4×4 kernel).
    let rgb = [(PixelFormat::Rgb8, 3, 203), (PixelFormat::Rgb8, 3, 256)];
    for (format, c, w) in cases.into_iter().chain(rgb) {
        // A third of the samples saturated (250–255), the rest anywhere.
        let data: Vec<u8> = (0..w * h * c)
            .map(|_| {
                let r = next();
                if r.is_multiple_of(3) {
                    250 + (r >> 8) as u8 % 6
                } else {
                    (r >> 16) as u8
                }
            })
            .collect();
        let frame = FrameView::new(format, w, h, &data).unwrap();
        for k in (1..=8).chain([16]) {
            let ow = w / k;
            for oy in [0, h / k - 1] {
                let rows = oy * k..(oy + 1) * k;
                let (mut luma, mut sat) = (vec![0.0f32; ow], vec![0.0f32; ow]);
                let mut bytes = vec![0u32; w * 3];
                block_sums_8bit(&frame, rows.clone(), c, k, &mut bytes, &mut luma);
                let mut scratch = SaturationScratch::default();
                saturated_sums_8bit(&frame, rows.clone(), c, k, &mut scratch, &mut sat);
                let (mut luma1, mut sat1) = (vec![-1.0f32; ow], vec![-1.0f32; ow]);
                let mut fused = FusedScratch::default();
                let at = BlockRows {
                    frame: &frame,
                    rows,
                    c,
                    k,
                };
                fused.block_row(at, &mut luma1, Some(&mut sat1));
                assert_eq!(luma1, luma, "{format:?}, k {k}, row {oy}");
                assert_eq!(sat1, sat, "{format:?}, k {k}, row {oy}");
                assert!(sat.iter().any(|&v| v > 0.0));
            }
        }
    }
}

/// The statistics as they were summed before they were taken in blocks of
/// four histograms: one pass, the partial sums indexed by the count.
fn stats_one_by_one<'a>(pixels: impl Iterator<Item = &'a f32>) -> ImageStats {
    let mut histogram = vec![0u32; HISTOGRAM_BINS];
    let (mut sum, mut count, mut sat, mut dark) = (0.0f64, 0usize, 0usize, 0usize);
    let mut partial = [0.0f32; 8];
    for &v in pixels {
        partial[count % 8] += v;
        count += 1;
        if count % 4096 == 0 {
            sum += f64::from(partial.iter().sum::<f32>());
            partial = [0.0; 8];
        }
        sat += usize::from(v >= SATURATED_LEVEL);
        dark += usize::from(v <= DARK_LEVEL);
        histogram[((v * HISTOGRAM_BINS as f32) as usize).min(HISTOGRAM_BINS - 1)] += 1;
    }
    sum += f64::from(partial.iter().sum::<f32>());
    let n = count.max(1) as f32;
    ImageStats {
        mean: (sum / count.max(1) as f64) as f32,
        median: histogram_quantile(&histogram, 0.5),
        saturated_fraction: sat as f32 / n,
        dark_fraction: dark as f32 / n,
        histogram,
        count,
    }
}

/// The blocked statistics are bit for bit those summed one pixel at a
/// time, over whole images and masked ones, of lengths around the block.
#[test]
fn blocked_statistics_equal_the_one_by_one_sums() {
    let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
    for len in [0, 1, 7, 8, 4095, 4096, 4097, 77_602] {
        let values: Vec<f32> = (0..len)
            .map(|_| match next() % 5 {
                0 => 1.0,
                1 => 0.0,
                _ => (next() >> 40) as f32 / (1u64 << 24) as f32,
            })
            .collect();
        let mask: Vec<bool> = (0..len).map(|_| !next().is_multiple_of(3)).collect();
        let whole = ImageStats::from_slice(&values);
        assert_eq!(whole, stats_one_by_one(values.iter()), "{len} pixels");
        let masked = || values.iter().zip(&mask).filter(|(_, &m)| m).map(|(v, _)| v);
        assert_eq!(
            ImageStats::from_pixels(masked()),
            stats_one_by_one(masked()),
            "{len} pixels, masked"
        );
        // The prepared mask's path: runs of the mask, copied run by run.
        let runs = runs_of(&mask);
        assert_eq!(
            runs.iter().map(|&(a, b)| b - a).sum::<usize>(),
            mask.iter().filter(|&&m| m).count()
        );
        assert_eq!(
            ImageStats::from_runs(&values, &runs),
            stats_one_by_one(masked()),
            "{len} pixels, masked, by runs"
        );
        if len > 100 {
            assert!(whole.saturated_fraction > 0.1 && whole.dark_fraction > 0.1);
        }
    }
}

/// Values outside [0, 1] and at the bins' edges fall in the bins of the
/// saturating conversion the histogram was first taken with.
#[test]
fn histogram_bins_of_edge_values() {
    let edges = [
        f32::NAN,
        f32::NEG_INFINITY,
        -0.5,
        -0.0,
        1.0 / 256.0 - f32::EPSILON / 4.0,
        1.0 / 256.0,
        0.5,
        255.0 / 256.0,
        1.0 - f32::EPSILON / 2.0,
        1.0,
        2.0,
        f32::INFINITY,
    ];
    let values: Vec<f32> = edges
        .iter()
        .cycle()
        .take(5 * edges.len() + 3)
        .copied()
        .collect();
    let mut expected = vec![0u32; HISTOGRAM_BINS];
    for &v in &values {
        expected[((v * HISTOGRAM_BINS as f32) as usize).min(HISTOGRAM_BINS - 1)] += 1;
    }
    assert_eq!(ImageStats::from_slice(&values).histogram, expected);
    assert!(expected[0] > 0 && expected[HISTOGRAM_BINS - 1] > 0 && expected[128] > 0);
}

/// Frames metered through the `f32` rows (Bayer mosaics, 12- and 16-bit
/// frames), compiled for AVX2 where the CPU has it, give the bits of the
/// same rows summed here in the baseline build, blocks of 4×4.
#[test]
fn float_rows_meter_as_the_baseline_sums() {
    let mut next = xorshift(0x5851_f42d_4c95_7f2d);
    let meter = square_meter(12);
    for format in PixelFormat::ALL {
        if matches!(format, PixelFormat::Mono8 | PixelFormat::Rgb8) {
            continue;
        }
        let bayer = format.is_bayer();
        // 12×12 blocks of 4×4 pixels or quads.
        let (gw, gh) = (48 + 3, 48 + 2);
        let (w, h) = if bayer { (2 * gw, 2 * gh) } else { (gw, gh) };
        let data: Vec<u8> = (0..w * h * format.bytes_per_pixel())
            .map(|_| (next() >> 24) as u8)
            .collect();
        let frame = FrameView::new(format, w, h, &data).unwrap();
        let m = meter.meter(&frame, None).unwrap();
        assert_eq!((m.width(), m.height()), (12, 12), "{format:?}");
        let (mut row, mut sums) = (vec![0.0f32; gw], vec![0.0f32; 12]);
        for oy in 0..12 {
            sums.fill(0.0);
            for gy in 4 * oy..4 * oy + 4 {
                if bayer {
                    let (top, bottom) = (frame.row(2 * gy), frame.row(2 * gy + 1));
                    luma::bayer_luma_row(format, top, bottom, &mut row);
                } else {
                    luma_row(format, frame.row(gy), &mut row);
                }
                for (s, block) in sums.iter_mut().zip(row.chunks_exact(4)) {
                    *s += block.iter().sum::<f32>();
                }
            }
            for (x, s) in sums.iter().enumerate() {
                let want = (s * (1.0 / 16.0)).clamp(0.0, 1.0);
                let got = m.luma()[oy * 12 + x];
                assert_eq!(got.to_bits(), want.to_bits(), "{format:?} ({x}, {oy})");
            }
        }
    }
}
