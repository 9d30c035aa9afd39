//! Thermal formats irfidelity recognises but does not read. Each is refused with a reason that
//! names the format and says what to convert the file to; [`UNREAD`] is the one list of their
//! names and advice. The signatures, and where each is documented:
//!
//! * DJI R-JPEG of the DJI Thermal SDK kind: a JPEG whose Exif Make is "DJI" with an APP4
//!   segment of thermal parameters in one of ExifTool's three layouts (`aa 55 12 06` at its
//!   start; `2c 01 20 00` after 32 or 64 bytes; `aa 55 38 00` after 32 bytes), the same tests
//!   ExifTool 13.58 makes (`lib/Image/ExifTool.pm`, APP4; `DJI.pm`, ThermalParams 1-3).
//! * InfiRay radiometric JPEG (IJPEG): an APP2 segment with `IJPEG\0` after its 4-byte version,
//!   ExifTool's test (`ExifTool.pm`, APP2; `InfiRay.pm`).
//! * HIKMICRO radiometric JPEG: an `HDRI` block right after an end-of-image marker, following the
//!   displayed JPEG (public HIKMICRO readers: Quadricopter/hikmicro, Higomon/hikmicropy).
//! * InfiRay IRG: a little-endian header whose first word is `ca ac`, `ba ab` or `b0 0b`, whose
//!   second is the header's length, and which ends in `ac ca` (jaseg/infiray_irg; the header
//!   povlhp/irgdump reverse-engineered).
//! * FLIR Research Studio radiometric JPEG: FLIR segments that hold no FFF frame but a
//!   "FLIR ATS-US File" (the block names seen in these files, EEVblog forum thread
//!   "Radiometric JPG & ATS file formats").
//!
//! A FLIR ATS recording (`.ats`) and an IRG whose first word no reader documents (InfiRay
//! P200's `04 a0`) have no established signature: a file whose first bytes match no format is
//! named by its extension instead.

use std::io::{BufRead, Read};

/// A format irfidelity recognises but does not read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Unread {
    DjiRjpeg,
    InfiRayJpeg,
    HikmicroJpeg,
    InfiRayIrg,
    FlirAts,
    ResearchStudioJpeg,
}

/// One unread format: what it is, what to do with it, and the file extension that names it
/// when its first bytes do not.
struct Entry {
    format: Unread,
    name: &'static str,
    advice: &'static str,
    extension: Option<&'static str>,
}

/// Save the converted frame as something irfidelity reads (common tail of the advice).
const READABLE: &str = "a TIFF (16-bit counts or float32 temperatures) or a .npy";

const UNREAD: [Entry; 6] = [
    Entry {
        format: Unread::DjiRjpeg,
        name: "a DJI R-JPEG of the H20T/H20N/M30T/M3T/M2EA kind (DJI Thermal SDK format)",
        advice: "convert it with the DJI Thermal SDK's dji_irp (-a measure writes its temperatures as raw \
                 values) and save those as",
        extension: None,
    },
    Entry {
        format: Unread::InfiRayJpeg,
        name: "an InfiRay radiometric JPEG (IJPEG)",
        advice: "export its temperatures with InfiRay's app or analysis software and save them as",
        extension: None,
    },
    Entry {
        format: Unread::HikmicroJpeg,
        name: "a HIKMICRO radiometric JPEG (HDRI block)",
        advice: "export its temperature matrix (CSV) with HIKMICRO Analyzer and save it as",
        extension: None,
    },
    Entry {
        format: Unread::InfiRayIrg,
        name: "an InfiRay IRG file",
        advice: "read it with the infiray-irg Python package (infiray_irg.load gives temperatures in °C) and \
                 save them as",
        extension: Some("irg"),
    },
    Entry {
        format: Unread::FlirAts,
        name: "a FLIR ATS recording (FLIR Research Studio/ResearchIR)",
        advice: "export its frames with FLIR Research Studio or ResearchIR as",
        extension: Some("ats"),
    },
    Entry {
        format: Unread::ResearchStudioJpeg,
        name: "a FLIR Research Studio radiometric JPEG (its FLIR segments hold an ATS file, not an FFF frame)",
        advice: "export the frame with FLIR Research Studio as",
        extension: None,
    },
];

impl Unread {
    fn entry(self) -> &'static Entry {
        UNREAD.iter().find(|e| e.format == self).expect("every unread format has an entry")
    }

    /// Why the file is refused (without the path).
    pub(crate) fn reason(self) -> String {
        let e = self.entry();
        format!("{}: irfidelity does not read it; {} {READABLE}", e.name, e.advice)
    }
}

/// The reason for a file whose first bytes match no format: named by its extension when that
/// is an unread format's.
pub(crate) fn unknown_format(name: &str) -> String {
    let generic = "unsupported file format (not an OpenEXR, PNG, TIFF or radiometric FLIR image by its magic bytes)";
    let extension = std::path::Path::new(name).extension().and_then(|x| x.to_str()).map(str::to_ascii_lowercase);
    let named = extension.as_deref().and_then(|x| UNREAD.iter().find(|e| e.extension == Some(x)));
    match named {
        Some(e) => format!(
            "{generic}; by its extension .{}, {}, which irfidelity does not read; {} {READABLE}",
            e.extension.unwrap_or_default(),
            e.name,
            e.advice
        ),
        None => generic.to_string(),
    }
}

/// InfiRay IRG header signatures: the first little-endian word (`ca ac`: C200/C201, `ba ab`:
/// other InfiRay OEM cameras, `b0 0b`: the camera of povlhp/irgdump) and the last.
const IRG_FIRST: [[u8; 2]; 3] = [[0xca, 0xac], [0xba, 0xab], [0xb0, 0x0b]];
const IRG_LAST: [u8; 2] = [0xac, 0xca];

/// The length of an IRG header when the file's first bytes could start one (its end marker is
/// checked by [`is_irg`]).
pub(crate) fn irg_header_len(head: &[u8]) -> Option<usize> {
    let first = [*head.first()?, *head.get(1)?];
    let len = usize::from(u16::from_le_bytes([*head.get(2)?, *head.get(3)?]));
    (IRG_FIRST.contains(&first) && len >= 8).then_some(len)
}

/// True when the stream (at its start) holds a whole IRG header ending in its end marker.
pub(crate) fn is_irg<R: Read>(reader: &mut R, header_len: usize) -> bool {
    let mut header = vec![0u8; header_len];
    reader.read_exact(&mut header).is_ok() && header.ends_with(&IRG_LAST)
}

/// What the APP segments of a JPEG without FLIR segments say about it.
#[derive(Debug, Default)]
pub(crate) struct JpegSigns {
    pub(crate) make_dji: bool,
    pub(crate) dji_thermal_params: bool,
    pub(crate) ijpeg: bool,
}

/// Bytes of an APP segment's start that [`JpegSigns::note`] looks at (APP1 is read whole, for
/// its Exif Make).
pub(crate) fn segment_head_len(marker: u8) -> usize {
    match marker {
        APP1 => usize::from(u16::MAX),
        APP2 => 10,
        APP4 => 68,
        _ => 0,
    }
}

const APP1: u8 = 0xE1;
const APP2: u8 = 0xE2;
const APP4: u8 = 0xE4;

impl JpegSigns {
    /// Take note of one segment, `head` being the first [`segment_head_len`] bytes of its body.
    pub(crate) fn note(&mut self, marker: u8, head: &[u8]) {
        match marker {
            APP1 => self.make_dji |= exif_make(head) == Some(b"DJI".as_slice()),
            APP2 => self.ijpeg |= head.get(4..10) == Some(b"IJPEG\0".as_slice()),
            APP4 => self.dji_thermal_params |= is_dji_thermal_params(head),
            _ => {}
        }
    }

    /// The format these signs name, in ExifTool's order (an IJPEG header makes the file
    /// InfiRay's whatever its Make).
    pub(crate) fn format(&self) -> Option<Unread> {
        if self.ijpeg {
            Some(Unread::InfiRayJpeg)
        } else if self.make_dji && self.dji_thermal_params {
            Some(Unread::DjiRjpeg)
        } else {
            None
        }
    }
}

/// An APP4 body in one of the three layouts of DJI's thermal parameters.
fn is_dji_thermal_params(app4: &[u8]) -> bool {
    let at = |offset: usize, magic: [u8; 4]| app4.get(offset..offset + 4) == Some(magic.as_slice());
    at(0, [0xaa, 0x55, 0x12, 0x06])
        || at(32, [0x2c, 0x01, 0x20, 0x00])
        || at(64, [0x2c, 0x01, 0x20, 0x00])
        || at(32, [0xaa, 0x55, 0x38, 0x00])
}

/// The Make (tag 0x010F, without its NUL) in the first IFD of an APP1 Exif body.
fn exif_make(app1: &[u8]) -> Option<&[u8]> {
    let tiff = app1.strip_prefix(b"Exif\0\0")?;
    let big = match tiff.get(..2)? {
        b"II" => false,
        b"MM" => true,
        _ => return None,
    };
    let u16_at = |at: usize| {
        tiff.get(at..at + 2)
            .map(|b| if big { u16::from_be_bytes([b[0], b[1]]) } else { u16::from_le_bytes([b[0], b[1]]) })
    };
    let u32_at = |at: usize| {
        tiff.get(at..at + 4).map(|b| {
            let b = [b[0], b[1], b[2], b[3]];
            usize::try_from(if big { u32::from_be_bytes(b) } else { u32::from_le_bytes(b) }).unwrap_or(usize::MAX)
        })
    };
    let ifd = u32_at(4)?;
    let entries = usize::from(u16_at(ifd)?);
    let entry = (0..entries).map(|i| ifd + 2 + 12 * i).find(|&at| u16_at(at) == Some(0x010F))?;
    let count = u32_at(entry + 4)?;
    let start = if count <= 4 { entry + 8 } else { u32_at(entry + 8)? };
    let value = tiff.get(start..start.checked_add(count)?)?;
    Some(value.split(|&b| b == 0).next().unwrap_or(value))
}

/// True when the rest of the stream holds an `HDRI` block right after an end-of-image marker
/// (HIKMICRO's raw thermal frame, after the JPEG images). Reads to the end of the file.
pub(crate) fn has_hikmicro_block<R: BufRead>(reader: &mut R) -> bool {
    const SIGN: &[u8] = b"\xFF\xD9HDRI";
    const KEPT: usize = SIGN.len() - 1;
    // the last bytes read, for a sign that straddles two reads
    let mut carry: Vec<u8> = Vec::new();
    loop {
        let chunk = match reader.fill_buf() {
            Ok([]) | Err(_) => return false,
            Ok(chunk) => chunk,
        };
        let seam: Vec<u8> = carry.iter().chain(chunk.iter().take(KEPT)).copied().collect();
        if seam.windows(SIGN.len()).any(|w| w == SIGN) || chunk.windows(SIGN.len()).any(|w| w == SIGN) {
            return true;
        }
        carry =
            if chunk.len() >= KEPT { &chunk[chunk.len() - KEPT..] } else { &seam[seam.len().saturating_sub(KEPT)..] }
                .to_vec();
        let n = chunk.len();
        reader.consume(n);
    }
}

/// True when the joined FLIR segments of a JPEG hold a FLIR Research Studio (ATS) file rather
/// than an FFF frame.
pub(crate) fn is_research_studio(flir_data: &[u8]) -> bool {
    const SIGN: &[u8] = b"FLIR ATS-US File";
    !super::flir::is_fff(flir_data) && flir_data.windows(SIGN.len()).any(|w| w == SIGN)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use std::io::Cursor;

    /// An APP1 Exif body whose first IFD holds one entry, Make.
    pub(crate) fn exif_with_make(make: &str, big: bool) -> Vec<u8> {
        // a number of `width` bytes in the file's byte order
        let put = |out: &mut Vec<u8>, value: u32, width: usize| {
            let bytes =
                if big { value.to_be_bytes()[4 - width..].to_vec() } else { value.to_le_bytes()[..width].to_vec() };
            out.extend(bytes);
        };
        let mut value = format!("{make}\0").into_bytes();
        let count = value.len() as u32;
        let mut out = b"Exif\0\0".to_vec();
        out.extend(if big { b"MM\0*" } else { b"II*\0" });
        put(&mut out, 8, 4);
        put(&mut out, 1, 2);
        put(&mut out, 0x010F, 2);
        put(&mut out, 2, 2);
        put(&mut out, count, 4);
        if value.len() <= 4 {
            value.resize(4, 0);
            out.extend(&value);
            put(&mut out, 0, 4);
        } else {
            put(&mut out, 8 + 2 + 12 + 4, 4);
            put(&mut out, 0, 4);
            out.extend(&value);
        }
        out
    }

    #[test]
    fn exif_make_is_read_in_both_byte_orders_inline_or_not() {
        assert_eq!(exif_make(&exif_with_make("DJI", false)), Some(b"DJI".as_slice()));
        assert_eq!(exif_make(&exif_with_make("DJI", true)), Some(b"DJI".as_slice()));
        assert_eq!(exif_make(&exif_with_make("FLIR Systems", true)), Some(b"FLIR Systems".as_slice()));
        assert_eq!(exif_make(b"http://ns.adobe.com/xap/1.0/\0"), None);
        let mut cut = exif_with_make("FLIR Systems", false);
        cut.truncate(cut.len() - 4);
        assert_eq!(exif_make(&cut), None);
    }

    #[test]
    fn dji_needs_its_make_and_a_thermal_parameter_layout() {
        let mut params = vec![0u8; 68];
        for (offset, magic) in [
            (0, [0xaa, 0x55, 0x12, 0x06]),
            (32, [0x2c, 1, 0x20, 0]),
            (64, [0x2c, 1, 0x20, 0]),
            (32, [0xaa, 0x55, 0x38, 0]),
        ] {
            params.fill(0);
            params[offset..offset + 4].copy_from_slice(&magic);
            let mut signs = JpegSigns::default();
            signs.note(APP4, &params);
            assert_eq!(signs.format(), None, "no Make yet");
            signs.note(APP1, &exif_with_make("DJI", false));
            assert_eq!(signs.format(), Some(Unread::DjiRjpeg), "{offset}");
        }
        let mut signs = JpegSigns::default();
        signs.note(APP1, &exif_with_make("DJI", false));
        signs.note(APP4, &[0u8; 68]);
        assert_eq!(signs.format(), None, "a DJI JPEG without thermal parameters");
    }

    #[test]
    fn ijpeg_header_names_infiray() {
        let mut signs = JpegSigns::default();
        signs.note(APP2, b"\x01\x00\x00\x00IJPEG\0");
        assert_eq!(signs.format(), Some(Unread::InfiRayJpeg));
        let mut icc = JpegSigns::default();
        icc.note(APP2, b"ICC_PROFILE\0");
        assert_eq!(icc.format(), None);
    }

    #[test]
    fn hikmicro_block_is_found_across_reads() {
        let mut file = vec![0x11u8; 100];
        file.extend(b"\xFF\xD9HDRI");
        file.extend([0u8; 40]);
        for capacity in [1, 3, 7, 64, 4096] {
            let mut reader = std::io::BufReader::with_capacity(capacity, Cursor::new(file.clone()));
            assert!(has_hikmicro_block(&mut reader), "capacity {capacity}");
        }
        let mut no_eoi = Cursor::new(b"\x11\x11HDRI\xFF\xD9".to_vec());
        assert!(!has_hikmicro_block(&mut no_eoi));
    }

    #[test]
    fn irg_header_needs_its_first_word_and_end_marker() {
        let mut header = vec![0u8; 128];
        header[..4].copy_from_slice(&[0xca, 0xac, 0x80, 0x00]);
        header[126..].copy_from_slice(&IRG_LAST);
        let len = irg_header_len(&header).unwrap();
        assert!(is_irg(&mut Cursor::new(&header), len));
        header[127] = 0;
        assert!(!is_irg(&mut Cursor::new(&header), len));
        assert!(!is_irg(&mut Cursor::new(&header[..64]), len), "truncated");
        assert_eq!(irg_header_len(&[0x04, 0xa0, 0x80, 0x00]), None, "P200's first word is not established");
        assert_eq!(irg_header_len(&[0xca, 0xac, 0x02, 0x00]), None);
    }

    #[test]
    fn every_unread_format_has_one_entry_and_a_one_line_reason() {
        for format in UNREAD.iter().map(|e| e.format) {
            assert_eq!(UNREAD.iter().filter(|e| e.format == format).count(), 1);
            let reason = format.reason();
            assert!(!reason.contains('\n') && reason.contains("does not read it"), "{reason}");
        }
    }

    #[test]
    fn unknown_bytes_are_named_by_an_unread_extension() {
        let ats = unknown_format("/data/Rec-0018.ATS");
        assert!(ats.starts_with("unsupported file format") && ats.contains("FLIR ATS recording"), "{ats}");
        assert!(unknown_format("x.irg").contains("InfiRay IRG"));
        assert!(!unknown_format("x.bin").contains("extension"));
    }
}
