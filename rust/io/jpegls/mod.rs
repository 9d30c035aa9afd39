//! JPEG-LS (ITU-T T.87 | ISO/IEC 14495-1) decoding, irfidelity's own: lossless and
//! near-lossless, one greyscale component of 2 to 16 bits, default or custom coding
//! parameters (an LSE segment), restart markers. FLIR CSQ recordings store each frame's raw
//! counts this way.
//!
//! This file reads the marker segments (`scan.rs` decodes the scan, `bits.rs` reads its bits).
//! What the standard allows but a thermal frame does not need is refused by name: several
//! components, mapping tables (palettes), a point transform, sizes given later (DNL) or in an
//! LSE extension. Sizes are checked against `max_pixels` and the memory against the budget
//! before anything is allocated.

mod bits;
mod scan;

use scan::Coding;

use super::{check_budget, check_size, frame_buffer, Reason};

/// A decoded image: `rows` lines of `cols` samples.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Image {
    pub cols: usize,
    pub rows: usize,
    pub samples: Vec<u16>,
}

const DHT: u8 = 0xC4;
const DAC: u8 = 0xCC;
const SOI: u8 = 0xD8;
const EOI: u8 = 0xD9;
const SOS: u8 = 0xDA;
const DQT: u8 = 0xDB;
const DNL: u8 = 0xDC;
const DRI: u8 = 0xDD;
const SOF55: u8 = 0xF7;
const LSE: u8 = 0xF8;
const COM: u8 = 0xFE;

/// Whether `bytes` start like a JPEG-LS stream: SOI, then (after any APPn/COM) SOF55 — told
/// apart from an ordinary JPEG only by the frame marker, so this checks the start alone.
pub(crate) fn is_jpeg(bytes: &[u8]) -> bool {
    bytes.starts_with(&[0xFF, SOI])
}

/// The frame header (SOF55).
#[derive(Debug, Clone, Copy)]
struct FrameHeader {
    bits: u32,
    cols: usize,
    rows: usize,
}

/// Preset coding parameters from an LSE segment; 0 means "the default".
#[derive(Debug, Clone, Copy, Default)]
struct Preset {
    maxval: i32,
    t1: i32,
    t2: i32,
    t3: i32,
    reset: i32,
}

/// Decode the JPEG-LS stream `bytes`, refusing more than `max_pixels` pixels or a decode
/// needing more than `max_bytes` bytes.
pub(crate) fn decode(bytes: &[u8], max_pixels: u64, max_bytes: u64) -> Result<Image, Reason> {
    if !is_jpeg(bytes) {
        return Err("not a JPEG-LS stream (no start-of-image marker)".to_string());
    }
    let (mut frame, mut preset, mut restart) = (None, Preset::default(), 0);
    let mut at = 2;
    loop {
        let (code, body, next) = segment(bytes, at)?;
        match code {
            SOF55 => frame = Some(frame_header(body, max_pixels)?),
            0xC0..=0xCF if !matches!(code, DHT | 0xC8 | DAC) => {
                return Err(format!(
                    "a JPEG coded with process SOF{} (marker 0xFF{code:02X}), not JPEG-LS (SOF55)",
                    code - 0xC0
                ))
            }
            LSE => preset = preset_parameters(body)?,
            DRI => restart = restart_interval(body)?,
            DNL => return Err("a JPEG-LS stream giving its line count after the scan (DNL) is not supported".into()),
            SOS => {
                let frame = frame.ok_or("corrupt JPEG-LS stream: a scan before the frame header (SOF55)")?;
                let near = scan_header(body)?;
                let coding = coding(frame.bits, near, preset)?;
                return decode_scan(&bytes[next..], frame, coding, restart, max_bytes);
            }
            // application data, comments, and the tables of other JPEG processes (skipped to
            // reach their frame header, which names the process)
            0xE0..=0xEF | COM | DQT | DHT | DAC => {}
            EOI => return Err("corrupt JPEG-LS stream: it ends before its scan".into()),
            other => return Err(format!("corrupt JPEG-LS stream: unexpected marker 0xFF{other:02X} before the scan")),
        }
        at = next;
    }
}

/// The image of the scan starting at `data`.
fn decode_scan(
    data: &[u8],
    frame: FrameHeader,
    coding: Coding,
    restart: usize,
    max_bytes: u64,
) -> Result<Image, Reason> {
    let FrameHeader { cols, rows, .. } = frame;
    let samples = (cols * rows) as u64; // both below 2^16
    let scratch = 2 * (cols as u64 + 2) * 4 + 2 * coding.maxval as u64 + 1; // two lines, the quantisation table
    let what = || format!("a {cols} x {rows} JPEG-LS image");
    check_budget(Some(2 * samples + scratch), what, max_bytes)?;
    let mut out = frame_buffer(cols * rows, 0u16)?;
    scan::decode(data, (cols, rows), coding, restart, &mut out)?;
    Ok(Image { cols, rows, samples: out })
}

/// The marker segment at `at`: its code, its body and where the next one starts.
fn segment(bytes: &[u8], at: usize) -> Result<(u8, &[u8], usize), Reason> {
    let truncated = || "truncated JPEG-LS stream (it ends in its headers)".to_string();
    if bytes.get(at) != Some(&0xFF) {
        return Err(format!("corrupt JPEG-LS stream: no marker at byte {at}"));
    }
    let code_at = at + 1 + bytes[at + 1..].iter().take_while(|&&b| b == 0xFF).count(); // fill bytes
    let code = *bytes.get(code_at).ok_or_else(truncated)?;
    if code == EOI || code == SOI {
        return Ok((code, &[], code_at + 1));
    }
    let len = bytes.get(code_at + 1..code_at + 3).ok_or_else(truncated)?;
    let len = usize::from(u16::from_be_bytes([len[0], len[1]]));
    if len < 2 {
        return Err(format!("corrupt JPEG-LS stream: segment 0xFF{code:02X} claims {len} bytes"));
    }
    let body = bytes.get(code_at + 3..code_at + 1 + len).ok_or_else(truncated)?;
    Ok((code, body, code_at + 1 + len))
}

fn word(body: &[u8], at: usize) -> i32 {
    i32::from(u16::from_be_bytes([body[at], body[at + 1]]))
}

fn too_short(what: &str, len: usize) -> Reason {
    format!("corrupt JPEG-LS stream: its {what} segment is too short ({len} bytes)")
}

/// The frame header: precision, size, and one component.
fn frame_header(body: &[u8], max_pixels: u64) -> Result<FrameHeader, Reason> {
    if body.len() < 6 {
        return Err(too_short("frame header (SOF55)", body.len()));
    }
    let (bits, rows, cols, components) = (u32::from(body[0]), word(body, 1), word(body, 3), body[5]);
    if !(2..=16).contains(&bits) {
        return Err(format!("corrupt JPEG-LS stream: {bits} bits per sample (JPEG-LS has 2 to 16)"));
    }
    if components != 1 {
        return Err(format!(
            "a JPEG-LS image of {components} components: irfidelity reads greyscale (one component) images"
        ));
    }
    if rows == 0 || cols == 0 {
        return Err(format!(
            "a JPEG-LS image of {cols} x {rows} pixels: sizes given later (DNL) or in an LSE extension are not supported"
        ));
    }
    check_size(cols as u64, rows as u64, max_pixels)?;
    Ok(FrameHeader { bits, cols: cols as usize, rows: rows as usize })
}

/// An LSE segment: preset coding parameters (id 1); mapping tables and size extensions are refused.
fn preset_parameters(body: &[u8]) -> Result<Preset, Reason> {
    match body.first() {
        Some(1) if body.len() >= 11 => Ok(Preset {
            maxval: word(body, 1),
            t1: word(body, 3),
            t2: word(body, 5),
            t3: word(body, 7),
            reset: word(body, 9),
        }),
        Some(1) => Err(too_short("preset parameters (LSE)", body.len())),
        Some(2 | 3) => Err("a JPEG-LS image with a mapping table (palette) is not supported".into()),
        Some(4) => Err("a JPEG-LS image with oversize dimensions (LSE id 4) is not supported".into()),
        Some(id) => Err(format!("corrupt JPEG-LS stream: LSE segment of unknown id {id}")),
        None => Err(too_short("LSE", 0)),
    }
}

/// The restart interval in lines (DRI; 2 to 4 bytes).
fn restart_interval(body: &[u8]) -> Result<usize, Reason> {
    if !(2..=4).contains(&body.len()) {
        return Err(format!("corrupt JPEG-LS stream: its restart interval (DRI) has {} bytes", body.len()));
    }
    Ok(body.iter().fold(0usize, |acc, &b| acc << 8 | usize::from(b)))
}

/// The scan header: one component, no mapping table, no point transform; returns NEAR.
fn scan_header(body: &[u8]) -> Result<i32, Reason> {
    match body.first() {
        Some(1) if body.len() >= 6 => {}
        Some(1) | None => return Err(too_short("scan header (SOS)", body.len())),
        Some(n) => return Err(format!("a JPEG-LS scan of {n} components: irfidelity reads greyscale images")),
    }
    if body[2] != 0 {
        return Err("a JPEG-LS image with a mapping table (palette) is not supported".into());
    }
    if body[4] > 2 {
        return Err(format!("corrupt JPEG-LS stream: interleave mode {} (0 to 2)", body[4]));
    }
    if body[5] & 0x0F != 0 {
        return Err(format!("a JPEG-LS image with a point transform ({}) is not supported", body[5] & 0x0F));
    }
    Ok(i32::from(body[3]))
}

/// The coding parameters of a scan: presets where given, the standard's defaults elsewhere
/// (T.87 §C.2.4.1.1), each checked against its allowed range.
///
/// A MAXVAL below 2^P − 1 sets RANGE, the code lengths and the clamping, as T.87 says (and as
/// ffmpeg decodes). CharLS instead codes with 2^P − 1 whatever MAXVAL its LSE segment states,
/// so its streams with such a MAXVAL decode differently here; thermal cameras use the full
/// range of their precision.
fn coding(bits: u32, near: i32, preset: Preset) -> Result<Coding, Reason> {
    let largest = (1i32 << bits) - 1;
    let maxval = if preset.maxval == 0 { largest } else { preset.maxval };
    if maxval > largest {
        return Err(format!("corrupt JPEG-LS stream: MAXVAL {maxval} does not fit {bits} bits"));
    }
    if near > (maxval / 2).min(255) {
        return Err(format!(
            "corrupt JPEG-LS stream: NEAR {near} is beyond {} for MAXVAL {maxval}",
            (maxval / 2).min(255)
        ));
    }
    let (t1, t2, t3) = default_thresholds(maxval, near);
    let pick = |given: i32, default: i32| if given == 0 { default } else { given };
    let coding = Coding {
        maxval,
        near,
        t1: pick(preset.t1, t1),
        t2: pick(preset.t2, t2),
        t3: pick(preset.t3, t3),
        reset: pick(preset.reset, 64),
    };
    let valid = (near + 1..=maxval).contains(&coding.t1)
        && (coding.t1..=maxval).contains(&coding.t2)
        && (coding.t2..=maxval).contains(&coding.t3)
        && (3..=maxval.max(255)).contains(&coding.reset);
    if !valid {
        return Err(format!("corrupt JPEG-LS stream: invalid preset coding parameters {preset:?}"));
    }
    Ok(coding)
}

/// The default thresholds T1, T2, T3 for MAXVAL and NEAR (T.87 §C.2.4.1.1).
fn default_thresholds(maxval: i32, near: i32) -> (i32, i32, i32) {
    let clamp = |t: i32, low: i32| if t > maxval || t < low { low } else { t };
    let (t1, t2, t3) = if maxval >= 128 {
        let factor = (maxval.min(4095) + 128) / 256;
        (factor + 2 + 3 * near, factor * 4 + 3 + 5 * near, factor * 17 + 4 + 7 * near)
    } else {
        let factor = 256 / (maxval + 1);
        ((3 / factor + 3 * near).max(2), (7 / factor + 5 * near).max(3), (21 / factor + 7 * near).max(4))
    };
    let t1 = clamp(t1, near + 1);
    let t2 = clamp(t2, t1);
    (t1, t2, clamp(t3, t2))
}

/// The offset of the next marker at or after `from` (an 0xFF followed by a code, not by a
/// stuffed byte or another fill 0xFF).
fn next_marker(data: &[u8], from: usize) -> Option<usize> {
    (from..data.len().saturating_sub(1)).find(|&i| data[i] == 0xFF && data[i + 1] >= 0x80 && data[i + 1] != 0xFF)
}

#[cfg(test)]
mod tests;
