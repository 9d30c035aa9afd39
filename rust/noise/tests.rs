use std::sync::Arc;

use super::engine::{run_pass, ArraySource};
use super::*;

/// A deterministic pseudo-random integer in `0..m` (xorshift).
fn rng(state: &mut u64, m: u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state % m
}

/// A T × V × H cube of u16 with every part present.
fn cube(t: usize, v: usize, h: usize, seed: u64) -> Vec<u16> {
    let mut s = seed | 1;
    let ft: Vec<i64> = (0..t).map(|_| rng(&mut s, 7) as i64).collect();
    let fv: Vec<i64> = (0..v).map(|_| rng(&mut s, 11) as i64).collect();
    let fh: Vec<i64> = (0..h).map(|_| rng(&mut s, 5) as i64).collect();
    let mut out = Vec::with_capacity(t * v * h);
    for &a in &ft {
        for &b in &fv {
            for &c in &fh {
                let x = 1000 + a + b + c + rng(&mut s, 13) as i64;
                out.push(x as u16);
            }
        }
    }
    out
}

fn pass(data: Samples<'_>, t: usize, v: usize, h: usize, workers: usize) -> Result<NoiseSums> {
    run_pass(&ArraySource { data, frames: t, rows: v, cols: h }, &PassOptions { workers, ..Default::default() })
}

/// Brute force in f64 from the definitions (directional means of the cube).
fn brute(x: &[f64], t: usize, v: usize, h: usize) -> ([f64; 7], f64) {
    let at = |a: usize, b: usize, c: usize| x[(a * v + b) * h + c];
    let n = (t * v * h) as f64;
    let m: f64 = x.iter().sum::<f64>() / n;
    let mt: Vec<f64> = (0..t).map(|a| (0..v * h).map(|i| at(a, i / h, i % h)).sum::<f64>() / (v * h) as f64).collect();
    let mv: Vec<f64> = (0..v).map(|b| (0..t * h).map(|i| at(i / h, b, i % h)).sum::<f64>() / (t * h) as f64).collect();
    let mh: Vec<f64> = (0..h).map(|c| (0..t * v).map(|i| at(i / v, i % v, c)).sum::<f64>() / (t * v) as f64).collect();
    let mtv = |a: usize, b: usize| (0..h).map(|c| at(a, b, c)).sum::<f64>() / h as f64;
    let mth = |a: usize, c: usize| (0..v).map(|b| at(a, b, c)).sum::<f64>() / v as f64;
    let mvh = |b: usize, c: usize| (0..t).map(|a| at(a, b, c)).sum::<f64>() / t as f64;
    let mut ss = [0.0; 7];
    let mut total = 0.0;
    for (a, &mta) in mt.iter().enumerate() {
        for (b, &mvb) in mv.iter().enumerate() {
            for (c, &mhc) in mh.iter().enumerate() {
                let nt = mta - m;
                let nv = mvb - m;
                let nh = mhc - m;
                let ntv = mtv(a, b) - m - nt - nv;
                let nth = mth(a, c) - m - nt - nh;
                let nvh = mvh(b, c) - m - nv - nh;
                let u = at(a, b, c) - m;
                let ntvh = u - nt - nv - nh - ntv - nth - nvh;
                for (k, p) in [nt, nv, nh, ntv, nth, nvh, ntvh].iter().enumerate() {
                    ss[k] += p * p;
                }
                total += u * u;
            }
        }
    }
    (ss, total)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1e-300)
}

#[test]
fn integer_parts_match_the_definitions_and_add_up_exactly() {
    let (t, v, h) = (6, 5, 7);
    let data = cube(t, v, h, 42);
    let sums = pass(Samples::U16(&data), t, v, h, 1).unwrap();
    let d = sums.finish().unwrap();
    let xs: Vec<f64> = data.iter().map(|&x| x as f64).collect();
    let (ss, total) = brute(&xs, t, v, h);
    for (k, name) in PARTS.iter().enumerate() {
        assert!(close(d.ss[k], ss[k], 1e-9), "part {name}: {} vs {}", d.ss[k], ss[k]);
    }
    assert!(close(d.ss_total, total, 1e-12));
    let exact = d.exact.unwrap();
    let mut sum = U256::ZERO;
    for part in &exact[..7] {
        sum = sum.checked_add(*part).unwrap();
    }
    assert_eq!(sum, exact[7]);
    assert!(close(d.mean, xs.iter().sum::<f64>() / xs.len() as f64, 1e-15));
}

#[test]
fn a_single_part_leaves_the_others_exactly_zero() {
    let (t, v, h) = (4, 3, 5);
    // only columns differ (h part): x = 100 + c
    let data: Vec<u16> = (0..t * v * h).map(|i| 100 + (i % h) as u16).collect();
    let d = pass(Samples::U16(&data), t, v, h, 1).unwrap().finish().unwrap();
    let exact = d.exact.unwrap();
    for (k, part) in exact[..7].iter().enumerate() {
        assert_eq!(*part == U256::ZERO, PARTS[k] != "h", "part {}", PARTS[k]);
    }
    // Σ N_h² = T·V·Σ(c − 2)² = 4·3·10
    assert_eq!(d.ss[2], 120.0);
}

#[test]
fn merge_equals_one_pass_for_integers() {
    let (t, v, h) = (9, 4, 6);
    let data = cube(t, v, h, 7);
    let whole = pass(Samples::U16(&data), t, v, h, 1).unwrap();
    let k = 4 * v * h;
    let a = pass(Samples::U16(&data[..k]), 4, v, h, 1).unwrap();
    let b = pass(Samples::U16(&data[k..]), t - 4, v, h, 1).unwrap();
    assert_eq!(a.merge(&b).unwrap(), whole);
}

#[test]
fn float_frames_agree_with_integer_frames_and_merge_closely() {
    let (t, v, h) = (11, 5, 6);
    let data = cube(t, v, h, 9);
    let floats: Vec<f32> = data.iter().map(|&x| x as f32 + 0.25).collect();
    let di = pass(Samples::U16(&data), t, v, h, 1).unwrap().finish().unwrap();
    let whole = pass(Samples::F32(&floats), t, v, h, 1).unwrap();
    let df = whole.finish().unwrap();
    for (k, name) in PARTS.iter().enumerate() {
        assert!(close(df.ss[k], di.ss[k], 1e-11), "part {name}: {} vs {}", df.ss[k], di.ss[k]);
    }
    assert!(close(df.mean, di.mean + 0.25, 1e-15));
    // a second range has another pivot: merging moves it onto the first's
    let k = 5 * v * h;
    let a = pass(Samples::F32(&floats[..k]), 5, v, h, 1).unwrap();
    let b = pass(Samples::F32(&floats[k..]), t - 5, v, h, 1).unwrap();
    let dm = a.merge(&b).unwrap().finish().unwrap();
    for (k, name) in PARTS.iter().enumerate() {
        assert!(close(dm.ss[k], df.ss[k], 1e-11), "merged part {name}");
    }
    let m1 = whole.row_means();
    let m2 = a.merge(&b).unwrap().row_means();
    assert!(m1.iter().zip(&m2).all(|(x, y)| close(*x, *y, 1e-14)));
}

#[test]
fn a_large_offset_costs_float_frames_no_precision() {
    // integer-valued float64 frames on offsets up to 1e12 (still exact in float64, each
    // value 1e12 + a few hundred): the same sums as the exact integer path without it
    let (t, v, h) = (8, 16, 16);
    let data = cube(t, v, h, 17);
    let exact = pass(Samples::U16(&data), t, v, h, 1).unwrap().finish().unwrap();
    for offset in [0.0, 1e6, 1e9, 1e12] {
        let floats: Vec<f64> = data.iter().map(|&x| x as f64 + offset).collect();
        let d = pass(Samples::F64(&floats), t, v, h, 2).unwrap().finish().unwrap();
        for (k, name) in PARTS.iter().enumerate() {
            assert!(close(d.ss[k], exact.ss[k], 1e-9), "{offset:e} part {name}: {} vs {}", d.ss[k], exact.ss[k]);
        }
        assert!(close(d.ss_total, exact.ss_total, 1e-12), "{offset:e}");
        assert!(close(d.mean, exact.mean + offset, 1e-15), "{offset:e}");
    }
}

#[test]
fn float_results_do_not_depend_on_the_worker_count() {
    let (t, v, h) = (40, 6, 7);
    let floats: Vec<f64> = cube(t, v, h, 3).iter().map(|&x| x as f64 * 0.1).collect();
    let one = pass(Samples::F64(&floats), t, v, h, 1).unwrap();
    let three = pass(Samples::F64(&floats), t, v, h, 3).unwrap();
    assert_eq!(one, three);
    let ints = cube(t, v, h, 3);
    assert_eq!(pass(Samples::U16(&ints), t, v, h, 1).unwrap(), pass(Samples::U16(&ints), t, v, h, 4).unwrap());
}

#[test]
fn bytes_round_trip_and_corrupt_bytes_fail() {
    let (t, v, h) = (3, 2, 4);
    let ints = cube(t, v, h, 5);
    let wide: Vec<u32> = ints.iter().map(|&x| x as u32 * 70000).collect();
    let floats: Vec<f32> = ints.iter().map(|&x| x as f32).collect();
    for sums in [
        pass(Samples::U16(&ints), t, v, h, 1).unwrap(),
        pass(Samples::U32(&wide), t, v, h, 1).unwrap(),
        pass(Samples::F32(&floats), t, v, h, 1).unwrap(),
    ] {
        let b = sums.to_bytes();
        assert_eq!(NoiseSums::from_bytes(&b).unwrap(), sums);
        assert!(NoiseSums::from_bytes(&b[..b.len() - 1]).is_err());
        let mut long = b.clone();
        long.push(0);
        assert!(NoiseSums::from_bytes(&long).is_err());
        let mut lying = b.clone();
        lying[4..12].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(NoiseSums::from_bytes(&lying).is_err());
        // a sum no pass could produce (the first per-pixel sum, or a float's sign bits)
        let mut impossible = b.clone();
        let first = 4 + 3 * 8 + 1 + if sums.dtype.is_int() { 6 * 8 } else { 3 * 8 + 1 };
        impossible[first..first + 8].copy_from_slice(&i64::MAX.to_le_bytes());
        let bad = NoiseSums::from_bytes(&impossible);
        assert!(bad.is_err(), "{:?}", sums.dtype);
    }
}

#[test]
fn wide_integers_are_exact() {
    let (t, v, h) = (3, 2, 3);
    let data: Vec<u32> = (0..t * v * h).map(|i| if i % 2 == 0 { u32::MAX } else { 0 }).collect();
    let d = pass(Samples::U32(&data), t, v, h, 1).unwrap().finish().unwrap();
    let xs: Vec<f64> = data.iter().map(|&x| x as f64).collect();
    let (ss, total) = brute(&xs, t, v, h);
    for k in 0..7 {
        assert!(close(d.ss[k], ss[k], 1e-9), "part {}", PARTS[k]);
    }
    assert!(close(d.ss_total, total, 1e-12));
}

#[test]
fn bad_frames_are_errors_naming_the_frame() {
    let (t, v, h) = (3, 2, 2);
    let mut floats = vec![1.0f32; t * v * h];
    floats[9] = f32::NAN;
    let err = pass(Samples::F32(&floats), t, v, h, 1).unwrap_err();
    assert!(matches!(&err, Error::Range(m) if m.contains("frame 2") && m.contains("row 0, column 1")), "{err}");
    let ints = vec![300u16; t * v * h];
    let opts = PassOptions { limits: Some((0, 255)), ..Default::default() };
    let err = run_pass(&ArraySource { data: Samples::U16(&ints), frames: t, rows: v, cols: h }, &opts).unwrap_err();
    assert!(matches!(&err, Error::Range(m) if m.contains("frame 0")), "{err}");
    let mut sums = NoiseSums::new(2, 2, Dtype::U16, None).unwrap();
    assert!(matches!(sums.add_frame(&[1u8; 4], 2, (0, 0), &|| "f".into()), Err(Error::Shape(_))));
    assert!(matches!(sums.add_frame(&[1u16; 3], 2, (0, 0), &|| "f".into()), Err(Error::Shape(_))));
    assert!(NoiseSums::new(2, 2, Dtype::U8, Some((0, 300))).is_err());
    assert!(sums.finish().is_err());
}

#[test]
fn a_window_equals_the_cropped_cube_and_counts_clipped_samples() {
    let (t, v, h) = (4, 5, 6);
    let data = cube(t, v, h, 11);
    let w = Window { row0: 1, col0: 2, rows: 3, cols: 3 };
    let mut crop = Vec::new();
    for a in 0..t {
        for b in 1..4 {
            for c in 2..5 {
                crop.push(data[(a * v + b) * h + c]);
            }
        }
    }
    let hi = *crop.iter().max().unwrap() as i64;
    let opts = PassOptions { window: Some(w), limits: Some((0, hi)), ..Default::default() };
    let windowed = run_pass(&ArraySource { data: Samples::U16(&data), frames: t, rows: v, cols: h }, &opts);
    let opts = PassOptions { limits: Some((0, hi)), ..Default::default() };
    let direct = run_pass(&ArraySource { data: Samples::U16(&crop), frames: t, rows: 3, cols: 3 }, &opts).unwrap();
    let windowed = windowed.unwrap();
    assert_eq!(windowed, direct);
    let clipped = windowed.value_range().clipped.unwrap();
    assert!(clipped.at_hi > 0);
    assert_eq!(clipped.at_hi, crop.iter().filter(|&&x| x as i64 == hi).count() as u64);
    // the whole frame holds values above the crop's maximum: outside the valid range
    let whole = PassOptions { limits: Some((0, hi)), ..Default::default() };
    let max_all = *data.iter().max().unwrap() as i64;
    let res = run_pass(&ArraySource { data: Samples::U16(&data), frames: t, rows: v, cols: h }, &whole);
    assert_eq!(res.is_err(), max_all > hi);
}

#[test]
fn pixel_maps_are_the_temporal_moments() {
    let (t, v, h) = (5, 2, 3);
    let data = cube(t, v, h, 13);
    let sums = pass(Samples::U16(&data), t, v, h, 1).unwrap();
    let (mean, var) = (sums.pixel_mean(), sums.pixel_var());
    for i in 0..v * h {
        let xs: Vec<f64> = (0..t).map(|a| data[a * v * h + i] as f64).collect();
        let m = xs.iter().sum::<f64>() / t as f64;
        let s2 = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / t as f64;
        assert!(close(mean[i], m, 1e-15) && close(var[i], s2, 1e-12));
    }
    let floats: Vec<f64> = data.iter().map(|&x| x as f64).collect();
    let fsums = pass(Samples::F64(&floats), t, v, h, 1).unwrap();
    assert!(fsums.pixel_var().iter().zip(&var).all(|(a, b)| close(*a, *b, 1e-12)));
    assert!(fsums.col_means().iter().zip(&sums.col_means()).all(|(a, b)| close(*a, *b, 1e-15)));
    let pivot = Arc::new(vec![0.0; 4]);
    assert_eq!(NoiseSums::with_pivot(2, 2, Dtype::F64, pivot).frames, 0);
}

#[test]
fn avx2_copy_of_the_integer_batch_loops_gives_the_same_sums() {
    let (t, v, h) = (8, 7, 37);
    let ints = cube(t, v, h, 21);
    let region = Region { stride: h, row0: 0, col0: 0, rows: v, cols: h };
    let frames: Vec<&[u16]> = ints.chunks_exact(v * h).collect();
    let label = |k: usize| format!("frame {k}");
    let mut base = IntAcc::new(v * h, false, (0, 65535));
    base.add_frames_baseline(&frames, &region, &label).unwrap();
    // the dispatcher takes one copy or the other: it must agree with the baseline
    let mut dispatched = IntAcc::new(v * h, false, (0, 65535));
    dispatched.add_frames(&frames, &region, &label).unwrap();
    assert_eq!(dispatched, base);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        let mut avx = IntAcc::new(v * h, false, (0, 65535));
        // SAFETY: the CPU reports AVX2 (checked just above).
        unsafe { avx.add_frames_avx2(&frames, &region, &label) }.unwrap();
        assert_eq!(avx, base);
        // and the error path: a value above the limit, found by the AVX2 copy too
        let mut strict = IntAcc::new(v * h, false, (0, 1005));
        // SAFETY: as above.
        let err = unsafe { strict.add_frames_avx2(&frames, &region, &label) }.unwrap_err();
        assert!(matches!(err, Error::Range(m) if m.contains("outside the valid range")));
    }
}
