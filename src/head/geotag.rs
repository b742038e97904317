//! What a view's still tells mapping software (OpenSfM/OpenDroneMap, Pix4D, exiftool) about
//! where and how it was taken, from the frame it was drawn from ([`Geotag`]): EXIF (the
//! vehicle's GPS position and altitude and the frame's capture time, in the GPS IFD and as
//! DateTimeOriginal with its sub-seconds and offset; make, model, the picture's size; the
//! focal length, its 35 mm equivalent and the focal plane's resolution of the view drawn as a
//! distortion-free pinhole on a 36 mm wide frame, left out for a panorama or a fisheye crop)
//! and an XMP packet with the view's orientation in the world in the form DJI's drones write
//! and OpenSfM reads (`drone-dji:GimbalYawDegree`, `GimbalPitchDegree`, `GimbalRollDegree`;
//! the vehicle's as `FlightYawDegree` ...). Both go into the encoded JPEG (APP1 segments) or
//! PNG (eXIf and iTXt chunks) before it is written.

use crate::geometry::GeoPosition;
use crate::state::capture::Geotag;
use crate::state::view::zoom::SENSOR_WIDTH_MM;
use bytes::Bytes;
use exif::experimental::Writer;
use exif::{Field, In, Rational, Tag, Value};
use img_parts::ImageEXIF;

/// Why a still's tags could not be written.
#[derive(Debug, thiserror::Error)]
pub enum GeotagError {
    #[error("EXIF: {0}")]
    Exif(#[from] exif::Error),
    #[error("the encoded still: {0}")]
    Image(#[from] img_parts::Error),
    #[error("the tagged still: {0}")]
    Io(#[from] std::io::Error),
    #[error("the capture time {0} µs is not a date")]
    Time(u64),
}

/// The still's bytes, as encoded (`png` or JPEG), with the tags of `tag` in them.
pub fn tagged(encoded: Vec<u8>, png: bool, tag: &Geotag) -> Result<Vec<u8>, GeotagError> {
    let exif = Bytes::from(exif(tag)?);
    let xmp = xmp(tag);
    let mut out = Vec::with_capacity(encoded.len() + exif.len() + xmp.len() + 64);
    if png {
        let mut image = img_parts::png::Png::from_bytes(encoded.into())?;
        image.set_exif(Some(exif));
        // iTXt: keyword, NUL, not compressed, method 0, no language, no translated keyword.
        let mut itxt = b"XML:com.adobe.xmp\0\0\0\0\0".to_vec();
        itxt.extend_from_slice(xmp.as_bytes());
        let chunk = img_parts::png::PngChunk::new(*b"iTXt", itxt.into());
        let n = image.chunks().len();
        image.chunks_mut().insert(n - 1, chunk);
        image.encoder().write_to(&mut out)?;
    } else {
        let mut image = img_parts::jpeg::Jpeg::from_bytes(encoded.into())?;
        image.set_exif(Some(exif));
        let mut app1 = b"http://ns.adobe.com/xap/1.0/\0".to_vec();
        app1.extend_from_slice(xmp.as_bytes());
        let segment = img_parts::jpeg::JpegSegment::new_with_contents(
            img_parts::jpeg::markers::APP1,
            app1.into(),
        );
        // After the EXIF segment, which set_exif puts first (after any JFIF APP0).
        let at = image
            .segments()
            .iter()
            .position(|s| s.marker() == img_parts::jpeg::markers::APP1)
            .map_or(0, |i| i + 1);
        image.segments_mut().insert(at, segment);
        image.encoder().write_to(&mut out)?;
    }
    Ok(out)
}

/// A rational of `v` with `denominator` (v ≥ 0).
fn rational(v: f64, denominator: u32) -> Rational {
    Rational {
        num: (v * denominator as f64).round() as u32,
        denom: denominator,
    }
}

/// Degrees, minutes and seconds (to a millionth of a second, 0.03 mm) of |deg|.
fn dms(deg: f64) -> Value {
    let deg = deg.abs();
    let whole = deg.floor();
    let minutes = ((deg - whole) * 60.0).floor();
    let seconds = ((deg - whole) * 60.0 - minutes) * 60.0;
    Value::Rational(vec![
        rational(whole, 1),
        rational(minutes, 1),
        rational(seconds, 1_000_000),
    ])
}

fn ascii(s: &str) -> Value {
    Value::Ascii(vec![s.as_bytes().to_vec()])
}

/// The frame's time: "YYYY:MM:DD", "HH:MM:SS", the seconds of the day's minute and the µs.
fn date_time(unix_us: u64) -> Result<(String, String, [u32; 3], u32), GeotagError> {
    let secs = (unix_us / 1_000_000) as i64;
    let micros = (unix_us % 1_000_000) as u32;
    let t = glib::DateTime::from_unix_utc(secs).map_err(|_| GeotagError::Time(unix_us))?;
    let text = |f: &str| {
        t.format(f)
            .map(|s| s.to_string())
            .map_err(|_| GeotagError::Time(unix_us))
    };
    let hms = [t.hour() as u32, t.minute() as u32, t.second() as u32];
    Ok((text("%Y:%m:%d")?, text("%H:%M:%S")?, hms, micros))
}

/// The EXIF fields of a still (TIFF byte order little-endian), as an EXIF APP1 payload
/// without its "Exif\0\0" header, which the containers add.
pub fn exif(tag: &Geotag) -> Result<Vec<u8>, GeotagError> {
    let (date, time, hms, micros) = date_time(tag.unix_us)?;
    let mut fields = vec![
        (Tag::Make, ascii("DigiView")),
        (Tag::Model, ascii(&format!("virtual camera {}", tag.camera))),
        (
            Tag::Software,
            ascii(concat!("DigiView ", env!("CARGO_PKG_VERSION"))),
        ),
        (Tag::DateTimeOriginal, ascii(&format!("{date} {time}"))),
        (Tag::SubSecTimeOriginal, ascii(&format!("{micros:06}"))),
        (Tag::OffsetTimeOriginal, ascii("+00:00")),
        (Tag::PixelXDimension, Value::Long(vec![tag.size.0])),
        (Tag::PixelYDimension, Value::Long(vec![tag.size.1])),
    ];
    fields.extend(gps_fields(&tag.position, &date, hms, micros));
    fields.extend(focal_fields(tag));
    let fields: Vec<Field> = fields
        .into_iter()
        .map(|(tag, value)| Field {
            tag,
            ifd_num: In::PRIMARY,
            value,
        })
        .collect();
    let mut writer = Writer::new();
    for f in &fields {
        writer.push_field(f);
    }
    let mut out = std::io::Cursor::new(Vec::new());
    writer.write(&mut out, true)?;
    Ok(out.into_inner())
}

/// Where and when (UTC) the still was taken, as GPS fields.
fn gps_fields(p: &GeoPosition, date: &str, [h, m, s]: [u32; 3], micros: u32) -> Vec<(Tag, Value)> {
    vec![
        (Tag::GPSVersionID, Value::Byte(vec![2, 3, 0, 0])),
        (
            Tag::GPSLatitudeRef,
            ascii(if p.lat < 0.0 { "S" } else { "N" }),
        ),
        (Tag::GPSLatitude, dms(p.lat)),
        (
            Tag::GPSLongitudeRef,
            ascii(if p.lon < 0.0 { "W" } else { "E" }),
        ),
        (Tag::GPSLongitude, dms(p.lon)),
        (Tag::GPSAltitudeRef, Value::Byte(vec![(p.alt < 0.0) as u8])),
        (
            Tag::GPSAltitude,
            Value::Rational(vec![rational(p.alt.abs(), 1000)]),
        ),
        (
            Tag::GPSTimeStamp,
            Value::Rational(vec![
                rational(h as f64, 1),
                rational(m as f64, 1),
                rational(s as f64 + micros as f64 * 1e-6, 1_000_000),
            ]),
        ),
        (Tag::GPSDateStamp, ascii(date)),
        (Tag::GPSMapDatum, ascii("WGS-84")),
    ]
}

/// A rectilinear view's focal length, as a pinhole on a 36 mm wide frame: its focal length
/// is its own 35 mm equivalent, and the focal plane's resolution gives the same ratio
/// exactly (the 35 mm figure is a whole number of millimetres). None for other views.
fn focal_fields(tag: &Geotag) -> Vec<(Tag, Value)> {
    let Some(fov) = tag
        .pinhole_fov
        .filter(|f| *f > 0.0 && *f < std::f64::consts::PI)
    else {
        return vec![];
    };
    let focal = SENSOR_WIDTH_MM / 2.0 / (fov / 2.0).tan();
    let per_cm = tag.size.0 as f64 / (SENSOR_WIDTH_MM / 10.0);
    vec![
        (
            Tag::FocalLength,
            Value::Rational(vec![rational(focal, 10_000)]),
        ),
        (
            Tag::FocalLengthIn35mmFilm,
            Value::Short(vec![focal.round().min(u16::MAX as f64) as u16]),
        ),
        (
            Tag::FocalPlaneXResolution,
            Value::Rational(vec![rational(per_cm, 1000)]),
        ),
        (
            Tag::FocalPlaneYResolution,
            Value::Rational(vec![rational(per_cm, 1000)]),
        ),
        (Tag::FocalPlaneResolutionUnit, Value::Short(vec![3])),
    ]
}

/// The XMP packet: the view's and the vehicle's orientation in degrees, as DJI writes them
/// (yaw from north, pitch up from the horizon, so -90 looks straight down).
pub fn xmp(tag: &Geotag) -> String {
    let deg = |r: f64| format!("{:+.4}", r.to_degrees());
    let (v, f) = (&tag.view, &tag.vehicle);
    format!(
        "<?xpacket begin=\"\u{feff}\" id=\"W5M0MpCehiHzreSzNTczkc9d\"?>\n\
         <x:xmpmeta xmlns:x=\"adobe:ns:meta/\">\n \
         <rdf:RDF xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\">\n  \
         <rdf:Description rdf:about=\"\" xmlns:drone-dji=\"http://www.dji.com/drone-dji/1.0/\"\n   \
         drone-dji:GimbalYawDegree=\"{}\" drone-dji:GimbalPitchDegree=\"{}\" \
         drone-dji:GimbalRollDegree=\"{}\"\n   \
         drone-dji:FlightYawDegree=\"{}\" drone-dji:FlightPitchDegree=\"{}\" \
         drone-dji:FlightRollDegree=\"{}\"\n   \
         drone-dji:RelativeAltitude=\"{:+.3}\"/>\n \
         </rdf:RDF>\n</x:xmpmeta>\n<?xpacket end=\"w\"?>",
        deg(v.yaw),
        deg(v.pitch),
        deg(v.roll),
        deg(f.yaw),
        deg(f.pitch),
        deg(f.roll),
        tag.position.relative_alt,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Euler, GeoPosition};

    fn tag() -> Geotag {
        Geotag {
            // 2026-11-27 01:02:03.456789 UTC
            unix_us: 1_795_741_323_456_789,
            position: GeoPosition {
                lat: -33.856_784_1,
                lon: 151.215_297_3,
                alt: 123.456,
                relative_alt: 100.0,
            },
            view: Euler::new(0.5, -0.6, 0.01),
            vehicle: Euler::new(0.4, 0.02, -0.03),
            pinhole_fov: Some(90f64.to_radians()),
            size: (1280, 720),
            camera: 2,
        }
    }

    /// What `exif` writes reads back, with the crate's own reader, as the numbers it was
    /// given: the position to a millionth of a second of arc, the time to the µs.
    #[test]
    fn the_exif_reads_back_as_the_frame_s_position_time_and_focal_length() {
        let t = tag();
        let bytes = exif(&t).unwrap();
        let read = exif::Reader::new().read_raw(bytes).unwrap();
        let get = |tag: Tag, ifd: In| read.get_field(tag, ifd).unwrap().value.clone();
        let text = |tag: Tag| match get(tag, In::PRIMARY) {
            Value::Ascii(v) => String::from_utf8(v[0].clone()).unwrap(),
            other => panic!("{other:?}"),
        };
        let degrees = |v: Value| match v {
            Value::Rational(r) => r[0].to_f64() + r[1].to_f64() / 60.0 + r[2].to_f64() / 3600.0,
            other => panic!("{other:?}"),
        };
        let lat = degrees(get(Tag::GPSLatitude, In::PRIMARY));
        let lon = degrees(get(Tag::GPSLongitude, In::PRIMARY));
        assert!((lat - 33.856_784_1).abs() < 1e-9 && (lon - 151.215_297_3).abs() < 1e-9);
        assert_eq!(text(Tag::GPSLatitudeRef), "S");
        assert_eq!(text(Tag::GPSLongitudeRef), "E");
        assert_eq!(text(Tag::DateTimeOriginal), "2026:11:27 01:02:03");
        assert_eq!(text(Tag::SubSecTimeOriginal), "456789");
        assert_eq!(text(Tag::GPSDateStamp), "2026:11:27");
        match get(Tag::FocalLength, In::PRIMARY) {
            Value::Rational(r) => assert!((r[0].to_f64() - 18.0).abs() < 1e-4, "{r:?}"),
            other => panic!("{other:?}"),
        }
        match get(Tag::GPSAltitude, In::PRIMARY) {
            Value::Rational(r) => assert!((r[0].to_f64() - 123.456).abs() < 1e-9),
            other => panic!("{other:?}"),
        }
    }

    /// In a JPEG and in a PNG alike the EXIF is where readers look for it (the crate's
    /// reader of containers finds it), the XMP packet is there once, and the picture still
    /// decodes to what was encoded.
    #[test]
    fn jpeg_and_png_stills_carry_both_and_still_decode() {
        let img =
            image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([x as u8 * 4, y as u8 * 5, 90]));
        for (format, png) in [
            (image::ImageFormat::Jpeg, false),
            (image::ImageFormat::Png, true),
        ] {
            let mut encoded = std::io::Cursor::new(Vec::new());
            img.write_to(&mut encoded, format).unwrap();
            let plain = image::load_from_memory(encoded.get_ref()).unwrap();
            let out = tagged(encoded.into_inner(), png, &tag()).unwrap();
            let read = exif::Reader::new()
                .read_from_container(&mut std::io::Cursor::new(&out))
                .unwrap_or_else(|e| panic!("{format:?}: {e}"));
            assert!(read.get_field(Tag::GPSLatitude, In::PRIMARY).is_some());
            let text = String::from_utf8_lossy(&out);
            assert_eq!(
                text.matches("drone-dji:GimbalYawDegree=\"+28.6479\"")
                    .count(),
                1
            );
            let back = image::load_from_memory(&out).unwrap();
            assert_eq!(
                back.to_rgb8().as_raw(),
                plain.to_rgb8().as_raw(),
                "{format:?}"
            );
        }
    }

    /// A panorama is no pinhole: no focal length is claimed for it.
    #[test]
    fn a_panorama_has_no_focal_length() {
        let t = Geotag {
            pinhole_fov: None,
            ..tag()
        };
        let read = exif::Reader::new().read_raw(exif(&t).unwrap()).unwrap();
        assert!(read.get_field(Tag::FocalLength, In::PRIMARY).is_none());
        assert!(read.get_field(Tag::GPSLatitude, In::PRIMARY).is_some());
    }
}
