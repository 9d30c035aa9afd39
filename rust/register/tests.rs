//! End-to-end registration on a real Lepton frame (tests/data/thermal) seen through known
//! transforms, and the refusals.

use std::path::PathBuf;

use super::*;
use crate::io::{decode_frame, DecodeOptions, FrameData};

/// The real 160×120 14-bit Lepton frame, lightly smoothed (an optics blur, so that the
/// resampled copies below are exact up to interpolation error).
fn lepton() -> Plane {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/thermal/cptv_v2_frame000.png");
    let frame = decode_frame(&path, &DecodeOptions::default()).unwrap();
    let FrameData::U16(data) = frame.data else { panic!("expected uint16") };
    Plane::from_samples(&data, frame.rows, frame.cols, None, "real").unwrap().smoothed(0.7)
}

/// Deterministic noise in [−1, 1).
fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut state = seed;
    (0..n)
        .map(|_| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

/// `sim(p) = gain·real(M p) + offset + noise`: the simulated frame of a scene whose map to
/// the real frame is `m`.
fn simulate(real: &Plane, m: &Affine, gain: f64, offset: f64, noise_amp: f64) -> Plane {
    let src = Source { data: &real.values[..], rows: real.rows, cols: real.cols, valid: None };
    let (values, valid) = warp(&src, m, Interp::Bicubic, real.rows, real.cols, 0.0);
    let n = noise(values.len(), 42);
    let values: Vec<f64> = values.iter().zip(&n).map(|(v, e)| gain * v + offset + noise_amp * e).collect();
    Plane::new(real.rows, real.cols, values, valid)
}

/// [`register_frames`] on planes.
fn register_planes(real: &Plane, sim: &Plane, opts: &Options) -> Result<Registration> {
    register_frames(&real.into(), &sim.into(), opts)
}

fn opts(model: Model, method: Method) -> Options {
    Options { model, method, max_shift: None }
}

fn centre_of(p: &Plane) -> (f64, f64) {
    ((p.cols as f64 - 1.0) / 2.0, (p.rows as f64 - 1.0) / 2.0)
}

#[test]
fn recovers_known_transforms_of_a_real_frame() {
    let real = lepton();
    let (_, std) = real.mean_std();
    let c = centre_of(&real);
    let cases = [
        (Model::Translation, Affine::translation(2.37, -1.61)),
        (Model::Rigid, Affine::translation(-1.2, 0.8).compose(&Affine::rotation_scale(2.5, 1.0, c))),
        (Model::Similarity, Affine::translation(0.6, 1.9).compose(&Affine::rotation_scale(-1.5, 1.015, c))),
    ];
    for (model, truth) in cases {
        let sim = simulate(&real, &truth, 1.3, 500.0, 0.2 * std);
        for method in [Method::Phase, Method::Auto] {
            let reg = register_planes(&real, &sim, &opts(model, method)).unwrap();
            let err = reg.matrix.corner_distance(&truth, real.rows, real.cols);
            assert!(err < 0.2, "{model:?} {method:?}: corner error {err} ({reg:?})");
            assert!(reg.confidence > LOW_CONFIDENCE && !reg.inverted, "{reg:?}");
            assert!(reg.overlap > 0.8 && reg.overlap <= 1.0);
        }
    }
}

#[test]
fn inverted_polarity_registers_with_phase_and_nmi() {
    let real = lepton();
    let truth = Affine::translation(-3.3, 2.45);
    let sim = simulate(&real, &truth, -0.7, 9000.0, 0.0);
    for method in [Method::Phase, Method::Nmi] {
        let reg = register_planes(&real, &sim, &opts(Model::Translation, method)).unwrap();
        let err = reg.matrix.corner_distance(&truth, real.rows, real.cols);
        assert!(err < 0.2, "{method:?}: {err} {reg:?}");
        assert!(reg.inverted);
        assert_eq!(reg.method, method);
    }
}

#[test]
fn any_sample_type_and_nan_pixels_are_excluded() {
    let real = lepton();
    let truth = Affine::translation(1.5, -2.25);
    let sim = simulate(&real, &truth, 1.0, 0.0, 0.0);
    let real_u16: Vec<u16> = real.values.iter().map(|v| v.round() as u16).collect();
    let mut sim_f32: Vec<f32> =
        sim.values.iter().zip(&sim.valid).map(|(&v, &ok)| if ok { v as f32 } else { f32::NAN }).collect();
    // a NaN blob (a dead area of the simulated frame) and a masked corner
    for r in 40..60 {
        for c in 70..95 {
            sim_f32[r * real.cols + c] = f32::NAN;
        }
    }
    let mut mask = vec![true; real.values.len()];
    mask[..real.cols * 10].iter_mut().for_each(|m| *m = false);
    let shape = (real.rows, real.cols);
    let reg = register(&real_u16, &sim_f32, shape, Some(&mask), &opts(Model::Translation, Method::Phase)).unwrap();
    let err = reg.matrix.corner_distance(&truth, real.rows, real.cols);
    assert!(err < 0.2, "{err} {reg:?}");
    let sim_f16: Vec<half::f16> = sim_f32.iter().map(|&v| half::f16::from_f32(v)).collect();
    let reg = register(&real_u16, &sim_f16, shape, None, &opts(Model::Translation, Method::Phase)).unwrap();
    assert!(reg.matrix.corner_distance(&truth, real.rows, real.cols) < 0.25);
}

fn refusal(real: &Plane, sim: &Plane, o: Options) -> String {
    match register_planes(real, sim, &o) {
        Err(Error::Registration(m)) => m,
        other => panic!("expected a registration error, got {other:?}"),
    }
}

#[test]
fn flat_and_empty_frames_are_refused() {
    let real = lepton();
    let flat = Plane::new(real.rows, real.cols, vec![2650.0; real.values.len()], vec![true; real.values.len()]);
    assert!(refusal(&real, &flat, opts(Model::Translation, Method::Auto)).contains("simulated frame is flat"));
    assert!(refusal(&flat, &real, opts(Model::Rigid, Method::Nmi)).contains("real frame is flat"));
    let empty = Plane::new(real.rows, real.cols, vec![0.0; real.values.len()], vec![false; real.values.len()]);
    assert!(refusal(&real, &empty, opts(Model::Translation, Method::Phase)).contains("0 valid pixels"));
    let tiny = Plane::new(4, 4, (0..16).map(f64::from).collect::<Vec<f64>>(), vec![true; 16]);
    assert!(refusal(&tiny, &tiny, opts(Model::Translation, Method::Phase)).contains("too small"));
}

#[test]
fn periodic_bars_are_ambiguous_unless_max_shift_resolves_them() {
    // a four-bar target filling the frame: 8-px period along x, uniform along y
    let (rows, cols) = (96, 128);
    let bars = |shift: f64| -> Plane {
        let values: Vec<f64> = (0..rows * cols)
            .map(|i| {
                let x = (i % cols) as f64 - shift;
                let phase = (x / 8.0).rem_euclid(1.0);
                1000.0 + 200.0 * (0.5 - (phase - 0.5).abs()) // smooth triangle bars
            })
            .collect();
        Plane::new(rows, cols, values, vec![true; rows * cols])
    };
    let (real, sim) = (bars(0.0), bars(-3.0));
    let msg = refusal(&real, &sim, opts(Model::Translation, Method::Phase));
    assert!(msg.contains("ambiguous"), "{msg}");
    let msg = refusal(&real, &sim, opts(Model::Translation, Method::Auto));
    assert!(msg.contains("ambiguous"), "{msg}");
}

#[test]
fn shifts_beyond_max_shift_and_missing_overlap_are_refused() {
    let real = lepton();
    let sim = simulate(&real, &Affine::translation(9.0, 0.0), 1.0, 0.0, 0.0);
    let o = Options { model: Model::Translation, method: Method::Phase, max_shift: Some(4.0) };
    assert!(refusal(&real, &sim, o).contains("max_shift=4"));
    let ok = Options { max_shift: Some(12.0), ..o };
    let reg = register_planes(&real, &sim, &ok).unwrap();
    assert!((reg.matrix.shift().1 - 9.0).abs() < 0.1, "{reg:?}");

    // the simulated frame sees mostly another part of a wider scene: 20 % overlap
    let wide = {
        let p = lepton();
        let (rows, cols) = (p.rows, 2 * p.cols);
        let mut values = vec![0.0; rows * cols];
        for r in 0..rows {
            for c in 0..cols {
                // the frame, then its mirror image: a continuous wider scene
                let src = if c < p.cols { c } else { 2 * p.cols - 1 - c };
                values[r * cols + c] = p.values[r * p.cols + src] + 3.0 * (c as f64 * 0.37).sin();
            }
        }
        Plane::new(rows, cols, values, vec![true; rows * cols])
    };
    let crop = |c0: usize| -> Plane {
        let (rows, cols) = (real.rows, real.cols);
        let mut values = Vec::with_capacity(rows * cols);
        for r in 0..rows {
            values.extend_from_slice(&wide.values[r * wide.cols + c0..r * wide.cols + c0 + cols]);
        }
        Plane::new(rows, cols, values, vec![true; rows * cols])
    };
    let msg = refusal(&crop(0), &crop(128), opts(Model::Translation, Method::Phase));
    assert!(msg.contains("no overlap") || msg.contains("ambiguous"), "{msg}");
}

#[test]
fn names_parse() {
    assert_eq!(Model::parse("rigid").unwrap(), Model::Rigid);
    assert!(Model::parse("affine").is_err());
    assert_eq!(Method::parse("nmi").unwrap().name(), "nmi");
    assert!(Method::parse("ecc").is_err());
}
