//! `sensor_msgs/PointCloud2` <-> [`Point3`]: decoding of any point layout into a reused buffer, and
//! building clouds for recordings.
//!
//! A [`Layout`] is read once from a cloud's `fields`, `point_step`, `row_step`, `height`, `width` and
//! `is_bigendian` and checked against the data length; decoding then walks the bytes with the
//! offsets it found. x, y and z may be `float32` or `float64` at any offsets; other fields (intensity,
//! ring, timestamps, padding) are skipped. The common layouts (all three coordinates the same type)
//! take a monomorphised loop; decoding a 29k-point Velodyne cloud costs tens of microseconds
//! (`cargo bench -p croprow-io --bench decode`).
//!
//! ```
//! use croprow_core::Point3;
//! use croprow_io::cloud::{self, PointFormat};
//! let cloud = cloud::build(&cloud::Stamped::new(1.0, "velodyne"), &[Point3::new(1.0, 2.0, 3.0)], &[7.0], &[4],
//!     PointFormat::VELODYNE).unwrap();
//! let mut points = Vec::new();
//! cloud::decode(&cloud, &mut points).unwrap();
//! assert_eq!(points, [Point3::new(1.0, 2.0, 3.0)]);
//! ```

use std::borrow::Cow;

use croprow_core::Point3;
use thiserror::Error;

use crate::msg::{Header, PointCloud2, PointField, Time};

/// A cloud whose layout cannot be decoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum LayoutError {
    /// A coordinate field is absent.
    #[error("point cloud has no `{0}` field (fields: {1})")]
    MissingField(&'static str, String),
    /// A coordinate is not float32/float64.
    #[error(
        "point cloud field `{name}` has datatype {datatype}; only float32 (7) and float64 (8) coordinates are supported"
    )]
    UnsupportedDatatype {
        /// Field name.
        name: &'static str,
        /// The datatype code found.
        datatype: u8,
    },
    /// A field does not fit inside one point.
    #[error(
        "point cloud field `{name}` at offset {offset} (+{size} bytes) runs past point_step {point_step}"
    )]
    FieldPastPointStep {
        /// Field name.
        name: &'static str,
        /// Its offset.
        offset: u32,
        /// Its size in bytes.
        size: u32,
        /// The point step.
        point_step: u32,
    },
    /// A row does not hold `width` points.
    #[error("point cloud row_step {row_step} is smaller than width {width} x point_step {point_step}")]
    RowStepTooSmall {
        /// Bytes per row.
        row_step: u32,
        /// Points per row.
        width: u32,
        /// Bytes per point.
        point_step: u32,
    },
    /// The data holds fewer bytes than the header promises.
    #[error("point cloud data has {actual} bytes but height {height} x row_step {row_step} needs {expected}")]
    DataTooShort {
        /// Bytes present.
        actual: usize,
        /// Bytes needed.
        expected: u64,
        /// Rows.
        height: u32,
        /// Bytes per row.
        row_step: u32,
    },
}

/// Type of one coordinate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    F32,
    F64,
}

/// Where x, y, z sit in a point and how to read them: validated once per cloud.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    offsets: [usize; 3],
    types: [Scalar; 3],
    big_endian: bool,
    point_step: usize,
    row_step: usize,
    width: usize,
    height: usize,
}

impl Layout {
    /// Reads and checks the layout of a cloud (not its data length: see [`Layout::check_data`]).
    pub fn of(cloud: &PointCloud2<'_>) -> Result<Self, LayoutError> {
        let mut offsets = [0usize; 3];
        let mut types = [Scalar::F32; 3];
        for (i, name) in ["x", "y", "z"].into_iter().enumerate() {
            let field = cloud.fields.iter().find(|f| f.name == name).ok_or_else(|| {
                let names: Vec<&str> = cloud.fields.iter().map(|f| f.name.as_str()).collect();
                LayoutError::MissingField(name, format!("[{}]", names.join(", ")))
            })?;
            let (ty, size) = match field.datatype {
                PointField::FLOAT32 => (Scalar::F32, 4),
                PointField::FLOAT64 => (Scalar::F64, 8),
                datatype => return Err(LayoutError::UnsupportedDatatype { name, datatype }),
            };
            if u64::from(field.offset) + u64::from(size) > u64::from(cloud.point_step) {
                return Err(LayoutError::FieldPastPointStep {
                    name,
                    offset: field.offset,
                    size,
                    point_step: cloud.point_step,
                });
            }
            offsets[i] = field.offset as usize;
            types[i] = ty;
        }
        if u64::from(cloud.row_step) < u64::from(cloud.width) * u64::from(cloud.point_step) {
            return Err(LayoutError::RowStepTooSmall {
                row_step: cloud.row_step,
                width: cloud.width,
                point_step: cloud.point_step,
            });
        }
        Ok(Self {
            offsets,
            types,
            big_endian: cloud.is_bigendian,
            point_step: cloud.point_step as usize,
            row_step: cloud.row_step as usize,
            width: cloud.width as usize,
            height: cloud.height as usize,
        })
    }

    /// Number of points the cloud holds (`width * height`).
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// True for a cloud without points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Checks that `data` holds `height * row_step` bytes.
    pub fn check_data(&self, data: &[u8]) -> Result<(), LayoutError> {
        let expected = self.height as u64 * self.row_step as u64;
        if (data.len() as u64) < expected {
            return Err(LayoutError::DataTooShort {
                actual: data.len(),
                expected,
                height: self.height as u32,
                row_step: self.row_step as u32,
            });
        }
        Ok(())
    }

    /// Decodes the points of `data` into `out` (cleared first; no allocation once `out` has the
    /// capacity). Non-finite points are kept: they are sensor dropouts the detector skips.
    pub fn decode(&self, data: &[u8], out: &mut Vec<Point3>) -> Result<(), LayoutError> {
        self.check_data(data)?;
        out.clear();
        out.reserve(self.len());
        let uniform = self.types[0] == self.types[1] && self.types[1] == self.types[2];
        let [ox, oy, oz] = self.offsets;
        // x, y, z packed one after the other (nearly every driver): one fixed-size read per point.
        if uniform && self.types[0] == Scalar::F32 && !self.big_endian && oy == ox + 4 && oz == ox + 8 {
            for row in self.rows(data) {
                out.extend(row.chunks_exact(self.point_step).map(|p| {
                    match p.get(ox..).and_then(|b| b.first_chunk::<12>()) {
                        Some(b) => {
                            let c = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
                            Point3::new(c(0), c(4), c(8))
                        }
                        None => Point3::new(f32::NAN, f32::NAN, f32::NAN),
                    }
                }));
            }
            return Ok(());
        }
        match (uniform, self.types[0], self.big_endian) {
            (true, Scalar::F32, false) => {
                self.decode_with(data, out, |b, o| read_f32(b, o, f32::from_le_bytes))
            }
            (true, Scalar::F32, true) => {
                self.decode_with(data, out, |b, o| read_f32(b, o, f32::from_be_bytes))
            }
            (true, Scalar::F64, false) => {
                self.decode_with(data, out, |b, o| read_f64(b, o, f64::from_le_bytes))
            }
            (true, Scalar::F64, true) => {
                self.decode_with(data, out, |b, o| read_f64(b, o, f64::from_be_bytes))
            }
            (false, ..) => {
                let (types, big) = (self.types, self.big_endian);
                let read = move |b: &[u8], o: usize, i: usize| match (types[i], big) {
                    (Scalar::F32, false) => read_f32(b, o, f32::from_le_bytes),
                    (Scalar::F32, true) => read_f32(b, o, f32::from_be_bytes),
                    (Scalar::F64, false) => read_f64(b, o, f64::from_le_bytes),
                    (Scalar::F64, true) => read_f64(b, o, f64::from_be_bytes),
                };
                self.decode_mixed(data, out, read)
            }
        }
        Ok(())
    }

    fn rows<'d>(&self, data: &'d [u8]) -> impl Iterator<Item = &'d [u8]> {
        // `Layout::of` guarantees point_step >= 4 (x fits inside it) and row_step >= width * point_step.
        let (row_step, row_len) = (self.row_step.max(1), self.width * self.point_step);
        data.chunks(row_step).take(self.height).map(move |row| row.get(..row_len).unwrap_or(row))
    }

    #[inline(always)]
    fn decode_with(&self, data: &[u8], out: &mut Vec<Point3>, read: impl Fn(&[u8], usize) -> f32) {
        let [ox, oy, oz] = self.offsets;
        for row in self.rows(data) {
            out.extend(
                row.chunks_exact(self.point_step).map(|p| Point3::new(read(p, ox), read(p, oy), read(p, oz))),
            );
        }
    }

    fn decode_mixed(&self, data: &[u8], out: &mut Vec<Point3>, read: impl Fn(&[u8], usize, usize) -> f32) {
        let [ox, oy, oz] = self.offsets;
        for row in self.rows(data) {
            out.extend(
                row.chunks_exact(self.point_step)
                    .map(|p| Point3::new(read(p, ox, 0), read(p, oy, 1), read(p, oz, 2))),
            );
        }
    }
}

// Offsets were checked against point_step in `Layout::of`, so `get` never fails for a point slice;
// NaN (a dropout) is the answer if it ever did, never a panic.
#[inline(always)]
fn read_f32(p: &[u8], o: usize, conv: fn([u8; 4]) -> f32) -> f32 {
    p.get(o..o + 4).and_then(|b| b.try_into().ok()).map_or(f32::NAN, conv)
}

#[inline(always)]
fn read_f64(p: &[u8], o: usize, conv: fn([u8; 8]) -> f64) -> f32 {
    p.get(o..o + 8).and_then(|b| b.try_into().ok()).map_or(f32::NAN, |b| conv(b) as f32)
}

/// Decodes a cloud's points into `out` (cleared first, reused: no allocation once large enough).
pub fn decode(cloud: &PointCloud2<'_>, out: &mut Vec<Point3>) -> Result<(), LayoutError> {
    Layout::of(cloud)?.decode(&cloud.data, out)
}

/// Stamp and frame of a cloud being built.
#[derive(Debug, Clone, PartialEq)]
pub struct Stamped<'a> {
    /// Scan stamp, s.
    pub stamp_s: f64,
    /// Sensor frame id.
    pub frame_id: &'a str,
}

impl<'a> Stamped<'a> {
    /// A stamp (s) and frame.
    pub fn new(stamp_s: f64, frame_id: &'a str) -> Self {
        Self { stamp_s, frame_id }
    }
}

/// How [`build`] lays points out: the layouts drivers and tools produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PointFormat {
    /// Coordinates as float64 instead of float32.
    pub xyz_f64: bool,
    /// Add a float32 `intensity` field.
    pub intensity: bool,
    /// Add a uint16 `ring` field.
    pub ring: bool,
    /// Extra bytes of padding at the end of every point (e.g. 16-byte aligned layouts).
    pub padding: u32,
    /// Big-endian data.
    pub big_endian: bool,
}

impl PointFormat {
    /// x y z intensity float32 + ring uint16, packed to 18 bytes, like the Velodyne driver.
    pub const VELODYNE: PointFormat =
        PointFormat { xyz_f64: false, intensity: true, ring: true, padding: 0, big_endian: false };
    /// x y z float32 only.
    pub const XYZ: PointFormat =
        PointFormat { xyz_f64: false, intensity: false, ring: false, padding: 0, big_endian: false };
}

/// Builds a `PointCloud2` (height 1) from sensor-frame points with per-point intensity and ring
/// (missing values are written as 0). Errors when the stamp cannot be represented.
pub fn build(
    at: &Stamped<'_>,
    points: &[Point3],
    intensity: &[f32],
    ring: &[u16],
    format: PointFormat,
) -> Result<PointCloud2<'static>, BuildError> {
    let stamp = Time::from_seconds(at.stamp_s).ok_or(BuildError::Stamp(at.stamp_s))?;
    let coord = if format.xyz_f64 { 8 } else { 4 };
    let datatype = if format.xyz_f64 { PointField::FLOAT64 } else { PointField::FLOAT32 };
    let mut fields = vec![
        PointField::new("x", 0, datatype),
        PointField::new("y", coord, datatype),
        PointField::new("z", 2 * coord, datatype),
    ];
    let mut step = 3 * coord;
    let intensity_at = format.intensity.then(|| {
        fields.push(PointField::new("intensity", step, PointField::FLOAT32));
        step += 4;
        step - 4
    });
    let ring_at = format.ring.then(|| {
        fields.push(PointField::new("ring", step, PointField::UINT16));
        step += 2;
        step - 2
    });
    let point_step = step + format.padding;
    let width = u32::try_from(points.len()).map_err(|_| BuildError::TooManyPoints(points.len()))?;
    let row_step = width.checked_mul(point_step).ok_or(BuildError::TooManyPoints(points.len()))?;
    let mut data = Vec::with_capacity(row_step as usize);
    let be = format.big_endian;
    for (i, p) in points.iter().enumerate() {
        let start = data.len();
        for c in [p.x, p.y, p.z] {
            match (format.xyz_f64, be) {
                (false, false) => data.extend_from_slice(&c.to_le_bytes()),
                (false, true) => data.extend_from_slice(&c.to_be_bytes()),
                (true, false) => data.extend_from_slice(&f64::from(c).to_le_bytes()),
                (true, true) => data.extend_from_slice(&f64::from(c).to_be_bytes()),
            }
        }
        if intensity_at.is_some() {
            let v = intensity.get(i).copied().unwrap_or(0.0);
            data.extend_from_slice(&if be { v.to_be_bytes() } else { v.to_le_bytes() });
        }
        if ring_at.is_some() {
            let v = ring.get(i).copied().unwrap_or(0);
            data.extend_from_slice(&if be { v.to_be_bytes() } else { v.to_le_bytes() });
        }
        data.resize(start + point_step as usize, 0);
    }
    Ok(PointCloud2 {
        header: Header { stamp, frame_id: at.frame_id.to_owned() },
        height: 1,
        width,
        fields,
        is_bigendian: be,
        point_step,
        row_step,
        data: Cow::Owned(data),
        is_dense: points.iter().all(Point3::is_finite),
    })
}

/// A cloud could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum BuildError {
    /// The stamp is not finite or out of the ROS time range.
    #[error("stamp {0} s cannot be written as a ROS time")]
    Stamp(f64),
    /// More points than a cloud can describe.
    #[error("{0} points do not fit a PointCloud2")]
    TooManyPoints(usize),
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_points() -> Vec<Point3> {
        vec![Point3::new(1.0, -2.0, 0.5), Point3::new(f32::NAN, 0.0, 0.0), Point3::new(-3.25, 4.5, -1.0)]
    }

    fn round_trip(format: PointFormat) -> Vec<Point3> {
        let cloud =
            build(&Stamped::new(2.5, "lidar"), &sample_points(), &[1.0, 2.0, 3.0], &[0, 1, 2], format)
                .unwrap();
        let mut out = Vec::new();
        decode(&cloud, &mut out).unwrap();
        out
    }

    fn same(a: &[Point3], b: &[Point3]) -> bool {
        a.len() == b.len()
            && a.iter().zip(b).all(|(p, q)| {
                [p.x, p.y, p.z]
                    .iter()
                    .zip([q.x, q.y, q.z])
                    .all(|(u, v)| u == &v || (u.is_nan() && v.is_nan()))
            })
    }

    #[test]
    fn every_format_round_trips_exactly() {
        for xyz_f64 in [false, true] {
            for intensity in [false, true] {
                for ring in [false, true] {
                    for padding in [0, 5] {
                        for big_endian in [false, true] {
                            let f = PointFormat { xyz_f64, intensity, ring, padding, big_endian };
                            assert!(same(&round_trip(f), &sample_points()), "{f:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn velodyne_layout_is_18_bytes() {
        let c = build(&Stamped::new(0.0, "v"), &sample_points(), &[], &[], PointFormat::VELODYNE).unwrap();
        assert_eq!(c.point_step, 18);
        assert_eq!(c.data.len(), 54);
    }

    #[test]
    fn mixed_types_and_organised_rows_with_row_padding() {
        // 2 rows x 2 points; x f64 at 8, y f32 at 0, z f32 at 4; point_step 16; row_step 40 (8 spare bytes).
        let mut data = Vec::new();
        let pts = [(1.0f64, 2.0f32, 3.0f32), (4.0, 5.0, 6.0), (7.0, 8.0, 9.0), (10.0, 11.0, 12.0)];
        for (r, row) in pts.chunks(2).enumerate() {
            for &(x, y, z) in row {
                data.extend_from_slice(&y.to_le_bytes());
                data.extend_from_slice(&z.to_le_bytes());
                data.extend_from_slice(&x.to_le_bytes());
            }
            data.extend_from_slice(&[0xAB; 8]);
            assert_eq!(data.len(), 40 * (r + 1));
        }
        let cloud = PointCloud2 {
            height: 2,
            width: 2,
            fields: vec![
                PointField::new("y", 0, PointField::FLOAT32),
                PointField::new("z", 4, PointField::FLOAT32),
                PointField::new("x", 8, PointField::FLOAT64),
            ],
            point_step: 16,
            row_step: 40,
            data: Cow::Owned(data),
            ..PointCloud2::default()
        };
        let mut out = Vec::new();
        decode(&cloud, &mut out).unwrap();
        let want: Vec<Point3> = pts.iter().map(|&(x, y, z)| Point3::new(x as f32, y, z)).collect();
        assert_eq!(out, want);
    }

    fn velodyne_cloud() -> PointCloud2<'static> {
        build(&Stamped::new(0.0, "v"), &sample_points(), &[], &[], PointFormat::VELODYNE).unwrap()
    }

    #[test]
    fn missing_x_is_an_error() {
        let mut c = velodyne_cloud();
        c.fields.retain(|f| f.name != "x");
        let e = decode(&c, &mut Vec::new()).unwrap_err();
        assert!(matches!(e, LayoutError::MissingField("x", _)), "{e}");
        assert!(e.to_string().contains("[y, z, intensity, ring]"), "{e}");
    }

    #[test]
    fn field_past_point_step_is_an_error() {
        let mut c = velodyne_cloud();
        c.fields[2].offset = 16;
        assert!(matches!(
            decode(&c, &mut Vec::new()),
            Err(LayoutError::FieldPastPointStep { name: "z", .. })
        ));
    }

    #[test]
    fn short_data_is_an_error() {
        let mut c = velodyne_cloud();
        c.data = Cow::Owned(c.data[..50].to_vec());
        assert!(matches!(
            decode(&c, &mut Vec::new()),
            Err(LayoutError::DataTooShort { actual: 50, expected: 54, .. })
        ));
    }

    #[test]
    fn integer_coordinates_are_refused() {
        let mut c = velodyne_cloud();
        c.fields[1].datatype = PointField::INT16;
        assert!(matches!(
            decode(&c, &mut Vec::new()),
            Err(LayoutError::UnsupportedDatatype { name: "y", datatype: 3 })
        ));
    }

    #[test]
    fn row_step_too_small_is_an_error() {
        let mut c = velodyne_cloud();
        c.row_step = 17;
        assert!(matches!(decode(&c, &mut Vec::new()), Err(LayoutError::RowStepTooSmall { .. })));
    }

    #[test]
    fn buffer_is_reused() {
        let c = velodyne_cloud();
        let mut out = Vec::with_capacity(64);
        let ptr = out.as_ptr();
        decode(&c, &mut out).unwrap();
        decode(&c, &mut out).unwrap();
        assert_eq!(out.len(), 3);
        assert_eq!(out.as_ptr(), ptr);
    }
}
