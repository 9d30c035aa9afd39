//! Unit tests over the real files in tests/data (no Python needed).

use super::*;
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(rel)
}

fn dec(rel: &str) -> Result<Frame> {
    decode_frame(&data(rel), &DecodeOptions::default())
}

fn dec_ch(rel: &str, ch: &str) -> Result<Frame> {
    decode_frame(&data(rel), &DecodeOptions { channel: Some(ch.to_string()), ..Default::default() })
}

fn frame_msg(r: Result<Frame>) -> String {
    match r {
        Err(Error::Frame(m)) => m,
        Err(other) => panic!("expected a Frame error, got {other:?}"),
        Ok(f) => panic!("expected an error, got a {}x{} frame", f.rows, f.cols),
    }
}

#[test]
fn png_16bit_grey() {
    let f = dec("png/pngsuite_basn0g16.png").unwrap();
    assert_eq!((f.rows, f.cols), (32, 32));
    let FrameData::U16(v) = &f.data else { panic!("not u16: {:?}", f.data.dtype_name()) };
    assert_eq!(*v.iter().max().unwrap(), 65535);
    assert_eq!(*v.iter().min().unwrap(), 0);
    // interlaced and split-IDAT variants decode to the same pixels
    for other in ["png/pngsuite_basi0g16.png", "png/pngsuite_oi4n0g16.png", "png/pngsuite_oi9n0g16.png"] {
        assert_eq!(dec(other).unwrap(), f, "{other}");
    }
}

#[test]
fn png_colour_needs_channel() {
    let m = frame_msg(dec("png/pngsuite_basn2c16.png"));
    assert!(m.contains("pngsuite_basn2c16.png") && m.contains("R, G, B"), "{m}");
    let g = dec_ch("png/pngsuite_basn2c16.png", "G").unwrap();
    assert!(matches!(g.data, FrameData::U16(_)));
    assert_eq!(dec_ch("png/pngsuite_basn2c16.png", "1").unwrap(), g);
    assert_eq!(list_channels(&data("png/pngsuite_basn6a16.png")).unwrap(), ["R", "G", "B", "A"]);
}

#[test]
fn thermal_png_tiff_exr_parity() {
    let png = dec("thermal/cptv_v2_frame000.png").unwrap();
    let tif = dec("thermal/cptv_v2_all100frames_uint16.tif").unwrap();
    assert_eq!(png, tif);
    let exr = dec("thermal/cptv_v2_frame000_counts_f32_zip.exr").unwrap();
    let (FrameData::U16(a), FrameData::F32(b)) = (&png.data, &exr.data) else { panic!("types") };
    assert_eq!((exr.rows, exr.cols), (120, 160));
    assert!(a.iter().zip(b).all(|(x, y)| *x as f32 == *y));
    let p1 = dec("thermal/cptv_v2_frame001.png").unwrap();
    let t1 = decode_frame(
        &data("thermal/cptv_v2_all100frames_uint16.tif"),
        &DecodeOptions { page: 1, ..Default::default() },
    )
    .unwrap();
    assert_eq!(p1, t1);
    assert_eq!(page_count(&data("thermal/cptv_v2_all100frames_uint16.tif")).unwrap(), 100);
    assert_eq!(page_count(&data("thermal/cptv_v2_frame000.png")).unwrap(), 1);
    let m = frame_msg(decode_frame(
        &data("thermal/cptv_v2_all100frames_uint16.tif"),
        &DecodeOptions { page: 100, ..Default::default() },
    ));
    assert!(m.contains("page 100 out of range"), "{m}");
}

#[test]
fn tiff_layouts_agree() {
    let base = dec("tiff/imagetiff_seq-1c-16b-bigendian-68f373a0.tiff").unwrap();
    assert!(matches!(base.data, FrameData::U16(_)));
    for v in ["deflate", "lzw", "multistrip", "tiled"] {
        let f = dec(&format!("tiff/imagetiff_seq-1c-16b-{v}-68f373a0.tiff")).unwrap();
        assert_eq!(f, base, "{v}");
    }
}

#[test]
fn tiff_sample_types() {
    assert_eq!(dec("tiff/imagetiff_int16.tif").unwrap().data.dtype_name(), "int16");
    assert_eq!(dec("tiff/imagetiff_gradient-1c-32b-float.tiff").unwrap().data.dtype_name(), "float32");
    assert_eq!(dec("tiff/imagetiff_gradient-1c-64b-float.tiff").unwrap().data.dtype_name(), "float64");
    assert_eq!(dec("tiff/libtiffpic_flower-minisblack-32.tif").unwrap().data.dtype_name(), "uint32");
    assert_eq!(page_count(&data("tiff/imagetiff_seq-1c-8b-multipage-adeefdcc.tiff")).unwrap(), 3);
    let rgb = frame_msg(dec("tiff/imagetiff_rgb-3c-16b.tiff"));
    assert!(rgb.contains("R, G, B"), "{rgb}");
    let r = dec_ch("tiff/imagetiff_rgb-3c-16b.tiff", "R").unwrap();
    assert_eq!((r.rows, r.cols), (151, 157));
}

#[test]
fn exr_lossless_compressions_agree() {
    let zip = dec_ch("exr/openexr_comp_zip.exr", "R").unwrap();
    let piz = dec_ch("exr/openexr_comp_piz.exr", "R").unwrap();
    assert_eq!((zip.rows, zip.cols), (675, 587));
    assert!(matches!(zip.data, FrameData::F16(_)));
    assert_eq!(zip, piz);
}

#[test]
fn exr_default_channel_and_listing() {
    let m = frame_msg(dec("exr/openexr_comp_zip.exr"));
    assert!(m.contains("openexr_comp_zip.exr") && m.contains("A, B, G, R"), "{m}");
    let y = dec("exr/exrimages_TestImages_GrayRampsHorizontal.exr").unwrap();
    assert_eq!((y.rows, y.cols), (800, 800));
    let chans = list_channels(&data("exr/tinyexr_flaga.exr")).unwrap();
    assert!(chans.contains(&"Warstwa 1.R".to_string()), "{chans:?}");
    dec_ch("exr/tinyexr_flaga.exr", "Warstwa 2.G").unwrap();
    // data window offset: output is the data window
    let z = dec_ch("exr/openexr_v1.7.test.1.exr", "Z").unwrap();
    assert_eq!((z.rows, z.cols, z.data.dtype_name()), (155, 178, "float32"));
    let id = dec_ch("exr/openexr_manifest_id.exr", "id").unwrap();
    assert_eq!(id.data.dtype_name(), "uint32");
}

#[test]
fn exr_tiled_and_mipmapped() {
    let g = dec_ch("exr/openexr_v1.7.test.tiled.exr", "G").unwrap();
    assert_eq!((g.rows, g.cols), (197, 217));
    let y = dec("exr/exrimages_LuminanceChroma_Garden.exr").unwrap();
    assert_eq!((y.rows, y.cols), (493, 874));
    let a = dec_ch("exr/exrimages_MultiResolution_ColorCodedLevels.exr", "A").unwrap();
    assert_eq!((a.rows, a.cols), (512, 512));
    let one = dec("exr/tinyexr_tiled_half_1x1_alpha.exr").unwrap();
    assert_eq!((one.rows, one.cols), (1, 1));
}

#[test]
fn exr_unsupported_are_clear() {
    let m = frame_msg(dec("exr/openexr_11.deep.exr"));
    assert!(m.contains("deep data"), "{m}");
    let m = frame_msg(dec("exr/openexr_comp_b44.exr"));
    assert!(m.contains("subsampl"), "{m}");
}

#[test]
fn max_pixels_refused_before_decoding() {
    for (f, ch) in [
        ("exr/openexr_comp_zip.exr", Some("R".to_string())),
        ("png/pngsuite_basn0g16.png", None),
        ("thermal/cptv_v2_all100frames_uint16.tif", None),
    ] {
        let m =
            frame_msg(decode_frame(&data(f), &DecodeOptions { channel: ch, max_pixels: 100, ..Default::default() }));
        assert!(m.contains("exceeds the limit of 100 pixels"), "{f}: {m}");
    }
    let m = frame_msg(dec("exr/damaged/exrimages_memory_DOS_1"));
    assert!(m.contains("exrimages_memory_DOS_1"), "{m}");
}

fn hostile_files() -> Vec<PathBuf> {
    let mut out = Vec::new();
    for d in ["exr/damaged", "png/corrupt", "tiff/corrupt"] {
        for e in std::fs::read_dir(data(d)).unwrap() {
            out.push(e.unwrap().path());
        }
    }
    out.sort();
    out
}

#[test]
fn damaged_files_error_cleanly() {
    for p in hostile_files() {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        for ch in [None, Some("R".to_string())] {
            match decode_frame(&p, &DecodeOptions { channel: ch, ..Default::default() }) {
                Err(Error::Frame(m)) => assert!(m.contains(&name), "{m}"),
                other => panic!("{name}: expected FrameError, got {other:?}"),
            }
        }
    }
}

#[test]
fn truncations_and_bit_flips_never_panic() {
    let files = [
        "thermal/cptv_v2_frame000.png",
        "thermal/cptv_v2_frame001_counts_f16_piz.exr",
        "thermal/cptv_v2_frame000_counts_f32_zip.exr",
        "tiff/imagetiff_seq-1c-16b-deflate-68f373a0.tiff",
        "tiff/imagetiff_seq-1c-16b-tiled-68f373a0.tiff",
        "exr/tinyexr_piz-bug-issue-100.exr",
        "exr/exrimages_TestImages_WideFloatRange.exr",
        "exr/exrimages_LuminanceChroma_Garden.exr",
    ];
    for f in files {
        let bytes = std::fs::read(data(f)).unwrap();
        let n = bytes.len();
        let full = decode_bytes(&bytes, f, &DecodeOptions::default()).unwrap();
        for cut in [0, 1, 4, 8, 16, 40, n / 4, n / 2, n - n / 8, n - 1] {
            // a truncated file is an error, or (cut inside trailing metadata only) the
            // very same frame: never different pixels
            match decode_bytes(&bytes[..cut], f, &DecodeOptions::default()) {
                Err(Error::Frame(m)) => assert!(m.starts_with(f), "{m}"),
                Ok(fr) => assert!(fr == full && cut > n / 2, "{f} cut at {cut}: decoded different pixels"),
                Err(e) => panic!("{f} cut at {cut}: {e:?}"),
            }
        }
        // bit flips: may decode (to different pixels) or fail, never panic out
        let mut state = 0x9E3779B97F4A7C15u64;
        for _ in 0..200 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let mut b = bytes.clone();
            let i = (state as usize) % n;
            b[i] ^= 1 << ((state >> 32) % 8);
            let _ = decode_bytes(&b, f, &DecodeOptions::default());
        }
    }
}

#[test]
fn tiff_pages_through_the_kept_chain_equal_fresh_decodes() {
    let path = data("thermal/cptv_v2_all100frames_uint16.tif");
    let bytes = std::fs::read(&path).unwrap();
    let page = |k: usize| DecodeOptions { page: k, ..Default::default() };
    // fresh decoder per page (in memory, never cached) as the reference
    let fresh = |k: usize| decode_bytes(&bytes, "ref", &page(k)).unwrap();
    // in order, then out of order (back, forward past the known IFDs, first, last)
    let order: Vec<usize> = (0..100).chain([50, 10, 99, 0, 3, 77, 98]).collect();
    for k in order {
        assert_eq!(decode_frame(&path, &page(k)).unwrap(), fresh(k), "page {k}");
    }
    assert!(frame_msg(decode_frame(&path, &page(100))).contains("page 100 out of range"));
    // a rewritten file is not read through a stale decoder
    let dir = std::env::temp_dir().join(format!("irf-cursor-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let copy = dir.join("seq.tif");
    std::fs::write(&copy, &bytes).unwrap();
    assert_eq!(decode_frame(&copy, &page(5)).unwrap(), fresh(5));
    let other = std::fs::read(data("thermal/ptw_lwir_all100frames_uint16.tif")).unwrap();
    std::fs::write(&copy, &other).unwrap();
    let want = decode_bytes(&other, "ref", &page(5)).unwrap();
    assert_eq!(decode_frame(&copy, &page(5)).unwrap(), want);
    std::fs::remove_dir_all(&dir).ok();
}

/// (IFD offset, offset of its next-IFD field) of each page of a little-endian classic TIFF.
fn classic_ifds(bytes: &[u8]) -> Vec<(usize, usize)> {
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let mut out = Vec::new();
    let mut at = u32_at(4);
    while at != 0 {
        let count = u16::from_le_bytes([bytes[at], bytes[at + 1]]) as usize;
        out.push((at, at + 2 + 12 * count));
        at = u32_at(at + 2 + 12 * count);
    }
    out
}

#[test]
fn a_truncated_tiff_gives_the_pages_before_the_break_and_names_it() {
    let bytes = std::fs::read(data("thermal/cptv_v2_all100frames_uint16.tif")).unwrap();
    let ifds = classic_ifds(&bytes);
    assert_eq!(ifds.len(), 100);
    let cut = &bytes[..ifds[60].0 + 10]; // page 60's IFD: its entry count, then the file ends
    let page = |k: usize| DecodeOptions { page: k, ..Default::default() };
    for k in [0, 30, 59] {
        assert_eq!(decode_bytes(cut, "cut", &page(k)).unwrap(), decode_bytes(&bytes, "whole", &page(k)).unwrap());
    }
    for k in [60, 61, 99, 100] {
        let m = frame_msg(decode_bytes(cut, "cut", &page(k)));
        let want = format!(
            "cut: truncated at page 60: its IFD at byte {} (12 entries) runs past the end of the file ({} bytes); \
             the 60 page(s) before it are found",
            ifds[60].0,
            cut.len()
        );
        assert_eq!(m, want);
    }
}

#[test]
fn a_looping_ifd_chain_is_read_up_to_the_loop() {
    let bytes = std::fs::read(data("thermal/cptv_v2_all100frames_uint16.tif")).unwrap();
    let ifds = classic_ifds(&bytes);
    let dir = std::env::temp_dir().join(format!("irf-loop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let page = |k: usize| DecodeOptions { page: k, ..Default::default() };
    for (back, name) in [(40usize, "back.tif"), (99, "self.tif")] {
        let mut looped = bytes.clone();
        let field = ifds[99].1;
        looped[field..field + 4].copy_from_slice(&(ifds[back].0 as u32).to_le_bytes());
        let path = dir.join(name);
        std::fs::write(&path, &looped).unwrap();
        let chain = page_chain(&path).unwrap();
        assert_eq!(chain.pages, 100);
        let why = chain.broken.unwrap();
        let want = format!(
            "{}: the IFD chain loops back at page 100: page 99's next-IFD offset points back to page {back}'s IFD \
             (byte {}); the 100 page(s) before it are found",
            path.display(),
            ifds[back].0
        );
        assert_eq!(why, want);
        match page_count(&path) {
            Err(Error::Frame(m)) => assert_eq!(m, why),
            other => panic!("a looping chain has no page count: {other:?}"),
        }
        // every page, the one with the looping link too, decodes as in the intact file
        for k in [0, back, 99] {
            assert_eq!(decode_frame(&path, &page(k)).unwrap(), decode_bytes(&bytes, "whole", &page(k)).unwrap());
        }
        assert_eq!(frame_msg(decode_frame(&path, &page(100))), why);
        assert_eq!(list_channels(&path).unwrap(), ["Y"]);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Our PIZ and ZIP decoders on images the `exr` crate writes: half, float and uint
/// channels side by side, scan lines and tiles, sizes from 1x1 to several blocks, and
/// value mixes that exercise both wavelet widths, long codes, runs and raw blocks.
#[test]
fn piz_and_zip_decoders_return_what_the_exr_crate_wrote() {
    use ::exr::prelude::*;
    use std::io::Cursor;

    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    // 0: small integers (14-bit wavelet), 1: every bit random (16-bit, long codes),
    // 2: constant with rare spikes (runs), 3: smooth ramp plus noise
    let mut words = |kind: u32, n: usize, i: usize| -> u32 {
        let r = next();
        match kind {
            0 => (r % 40) as u32,
            1 => r as u32,
            2 => {
                if r % 97 == 0 {
                    (r >> 8) as u32
                } else {
                    7
                }
            }
            _ => (i as u32 * 13 + (r % 5) as u32) % (n as u32 + 1),
        }
    };
    let mut cases = 0;
    for compression in [Compression::PIZ, Compression::ZIP16, Compression::ZIP1] {
        for &(w, h) in &[(1usize, 1usize), (3, 5), (17, 33), (64, 40), (150, 70)] {
            for kind in 0..4 {
                for tiled in [false, true] {
                    let n = w * h;
                    let y: Vec<f16> = (0..n).map(|i| f16::from_bits(words(kind, n, i) as u16)).collect();
                    let z: Vec<f32> = (0..n).map(|i| f32::from_bits(words(kind, n, i) & 0xbfff_ffff)).collect();
                    let id: Vec<u32> = (0..n).map(|i| words(kind, n, i)).collect();
                    let channels: Vec<AnyChannel<FlatSamples>> = vec![
                        AnyChannel::new("A", FlatSamples::F32(z.clone())),
                        AnyChannel::new("B", FlatSamples::U32(id.clone())),
                        AnyChannel::new("Y", FlatSamples::F16(y.clone())),
                    ];
                    let blocks = if tiled { Blocks::Tiles(Vec2(16, 16)) } else { Blocks::ScanLines };
                    let encoding = Encoding { compression, blocks, line_order: LineOrder::Increasing };
                    let layer =
                        Layer::new((w, h), LayerAttributes::named(""), encoding, AnyChannels::sort(channels.into()));
                    let mut bytes = Vec::new();
                    Image::from_layer(layer).write().to_buffered(Cursor::new(&mut bytes)).unwrap();
                    let what = format!("{compression:?} {w}x{h} kind {kind} tiled {tiled}");
                    let opts = |c: &str| DecodeOptions { channel: Some(c.to_string()), ..Default::default() };
                    let f = decode_bytes(&bytes, "piz.exr", &opts("Y")).unwrap();
                    let FrameData::F16(got) = f.data else { panic!("{what}: Y not f16") };
                    assert!(got.iter().zip(&y).all(|(a, b)| a.to_bits() == b.to_bits()), "{what}: Y");
                    let f = decode_bytes(&bytes, "piz.exr", &opts("A")).unwrap();
                    let FrameData::F32(got) = f.data else { panic!("{what}: A not f32") };
                    assert!(got.iter().zip(&z).all(|(a, b)| a.to_bits() == b.to_bits()), "{what}: A");
                    let f = decode_bytes(&bytes, "piz.exr", &opts("B")).unwrap();
                    assert_eq!(f.data, FrameData::U32(id), "{what}: B");
                    cases += 1;
                }
            }
        }
    }
    assert_eq!(cases, 120);
}

/// A 4×4 palette PNG whose PLTE chunk holds `palette_bytes` bytes.
fn palette_png(palette_bytes: usize) -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], body: &[u8]) {
        out.extend((body.len() as u32).to_be_bytes());
        let start = out.len();
        out.extend(kind);
        out.extend(body);
        let mut crc = flate2::Crc::new();
        crc.update(&out[start..]);
        let crc = crc.sum();
        out.extend(crc.to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    chunk(&mut png, b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 4, 8, 3, 0, 0, 0]);
    chunk(&mut png, b"PLTE", &(0..palette_bytes).map(|i| i as u8).collect::<Vec<_>>());
    let rows: Vec<u8> = (0..4).flat_map(|_| [0u8, 0, 1, 0, 1]).collect();
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    std::io::Write::write_all(&mut z, &rows).unwrap();
    chunk(&mut png, b"IDAT", &z.finish().unwrap());
    chunk(&mut png, b"IEND", &[]);
    png
}

#[test]
fn png_partial_palette_entry_is_a_frame_error() {
    // the png crate panics on a PLTE whose length is not a multiple of 3 (a fuzzing finding)
    let opts = DecodeOptions { channel: Some("R".into()), ..Default::default() };
    for bytes in [4, 5, 8] {
        let m = frame_msg(decode_bytes(&palette_png(bytes), "pal.png", &opts));
        assert!(m.starts_with(&format!("pal.png: corrupt PNG file: the PLTE chunk holds {bytes} bytes")), "{m}");
    }
    let m = frame_msg(decode_bytes(&palette_png(3 * 256 + 3), "pal.png", &opts));
    assert!(m.starts_with("pal.png: corrupt") && m.contains("PLTE"), "{m}");
    let f = decode_bytes(&palette_png(6), "pal.png", &opts).unwrap();
    assert_eq!((f.rows, f.cols), (4, 4));
}

#[test]
fn a_panic_in_a_guarded_decode_is_a_frame_error_naming_where() {
    let err = guarded::<()>("f.png", || panic!("boom")).unwrap_err();
    let Error::Frame(m) = err else { panic!("not a FrameError: {err:?}") };
    assert!(
        m.starts_with("f.png: decoder failed (a decoder bug at ") && m.contains("tests.rs:") && m.ends_with(": boom"),
        "{m}"
    );
    // nested guards restore the outer one's state
    let outer = guarded::<()>("outer", || {
        let _ = guarded::<()>("inner", || panic!("inner"));
        panic!("outer")
    });
    assert!(matches!(outer, Err(Error::Frame(m)) if m.starts_with("outer: decoder failed (a decoder bug at ")));
}

/// A 128-byte InfiRay IRG header with first word `first`, followed by some data.
fn irg(first: [u8; 2], end: [u8; 2]) -> Vec<u8> {
    let mut file = vec![0u8; 256];
    file[..4].copy_from_slice(&[first[0], first[1], 0x80, 0x00]);
    file[126..128].copy_from_slice(&end);
    file
}

#[test]
fn unread_formats_are_refused_by_name() {
    let msg = |bytes: &[u8], name: &str| match decode_bytes(bytes, name, &DecodeOptions::default()) {
        Err(Error::Frame(m)) => m,
        other => panic!("expected a FrameError, got {other:?}"),
    };
    for first in [[0xca, 0xac], [0xba, 0xab], [0xb0, 0x0b]] {
        let m = msg(&irg(first, [0xac, 0xca]), "x.bin");
        assert!(m.starts_with("x.bin: an InfiRay IRG file: irfidelity does not read it; "), "{m}");
    }
    let not_irg = msg(&irg([0xca, 0xac], [0, 0]), "x.bin");
    assert!(not_irg.starts_with("x.bin: unsupported file format") && !not_irg.contains("IRG"), "{not_irg}");
    // no established signature: named by the extension
    let p200 = msg(&irg([0x04, 0xa0], [0, 0]), "IMG_0001.irg");
    assert!(p200.contains("by its extension .irg, an InfiRay IRG file"), "{p200}");
    let ats = msg(b"\x01\x02\x03\x04 some FLIR recording", "Rec-0018.ats");
    assert!(ats.contains("by its extension .ats, a FLIR ATS recording"), "{ats}");
    // the refusal comes before the page check
    let page = DecodeOptions { page: 1, ..Default::default() };
    assert!(decode_bytes(&irg([0xca, 0xac], [0xac, 0xca]), "x", &page).is_err_and(|e| e.to_string().contains("IRG")));
}

#[test]
fn a_decoded_frames_calibration_is_kept_until_its_file_changes() {
    let dir = std::env::temp_dir().join(format!("irfidelity-calibrations-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let copy = dir.join("frame.jpg");
    let opts = DecodeOptions::default();
    for (name, other) in [
        ("radiometric/readthermal_flir_ax8.jpg", "radiometric/readthermal_zenmuse_xtr.jpg"),
        ("radiometric/flirpy_frame_000000.fff", "radiometric/flirpy_frame_000000_le.fff"),
    ] {
        let read = |rel: &str| {
            let bytes = std::fs::read(data(rel)).unwrap();
            (read_camera_info_bytes(&bytes, rel, &opts).unwrap(), bytes)
        };
        let ((first, first_bytes), (second, second_bytes)) = (read(name), read(other));
        assert_ne!(first, second, "{name}");
        std::fs::write(&copy, &first_bytes).unwrap();
        decode_frame(&copy, &opts).unwrap();
        assert_eq!(read_camera_info(&copy, &opts).unwrap(), first, "{name}");
        // rewritten in place: its key changes (size, times), so the new content is read
        std::fs::write(&copy, &second_bytes).unwrap();
        assert_eq!(read_camera_info(&copy, &opts).unwrap(), second, "{name}");
        decode_frame(&copy, &opts).unwrap();
        assert_eq!(read_camera_info(&copy, &opts).unwrap(), second, "{name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
