//! Point-cloud map files (PCD, PLY, LAS, whitespace-separated text) in and out, and the GeoJSON of the
//! rows extracted from them ([`croprow_core::mapping`]). This is the file side of `croprow rows`.
//!
//! Every reader returns `[x, y, z]` in `f64`, in the file's own frame and units (UTM-like offsets keep
//! their precision), and refuses a file it cannot fully trust with an error naming the file and the
//! problem: unknown or malformed header, truncated data, no finite point.
//!
//! Points with a NaN or infinite coordinate are skipped and counted ([`Cloud::non_finite`]): PCL's
//! organised clouds keep one entry per beam and write NaN for a beam without a return, so such a
//! point is a documented "nothing there", not damage.
//!
//! ```no_run
//! let cloud = croprow_io::maps::read(std::path::Path::new("field.pcd"))?;
//! println!("{} points ({} without a return skipped)", cloud.points.len(), cloud.non_finite);
//! # Ok::<(), croprow_io::maps::Error>(())
//! ```

mod geojson;
mod las;
mod pcd;
mod ply;
mod text;

use std::path::{Path, PathBuf};

use thiserror::Error;

pub use geojson::rows_to_geojson;
pub use ply::Encoding as PlyEncoding;

/// A map file that could not be read or written. Always names the file.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum Error {
    /// The operating system refused (missing file, permissions, disk full).
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The file's content is not a valid cloud of this format.
    #[error("{path}: {problem}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong, with the line, field or point where it applies.
        problem: String,
    },
    /// The extension names no supported format.
    #[error("{path}: unknown point-cloud format (expected .pcd, .ply, .las, or .txt/.xyz/.pts text)")]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
}

impl Error {
    pub(crate) fn invalid(path: &Path, problem: impl Into<String>) -> Self {
        Self::Invalid { path: path.to_path_buf(), problem: problem.into() }
    }

    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io { path: path.to_path_buf(), source }
    }
}

/// A point-cloud file format, chosen by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// PCL's PCD (ascii or binary).
    Pcd,
    /// Stanford PLY (ascii, binary little or big endian).
    Ply,
    /// ASPRS LAS.
    Las,
    /// Whitespace-separated `x y z [more columns]`, `#` comments, blank lines allowed.
    Text,
}

impl Format {
    /// The format of a path by its extension (case-insensitive), if supported.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "pcd" => Some(Self::Pcd),
            "ply" => Some(Self::Ply),
            "las" => Some(Self::Las),
            "txt" | "xyz" | "pts" => Some(Self::Text),
            _ => None,
        }
    }
}

/// The points of a map file.
#[derive(Debug, Clone, PartialEq)]
pub struct Cloud {
    /// Every point with three finite coordinates, `[x, y, z]` in the file's frame and units, in file
    /// order.
    pub points: Vec<[f64; 3]>,
    /// Points skipped because a coordinate was NaN or infinite (missing returns of organised clouds).
    pub non_finite: usize,
}

/// Reads a map file, the format chosen by extension: its finite points and how many were skipped.
/// A file without a single finite point is an error.
pub fn read(path: &Path) -> Result<Cloud, Error> {
    let format = Format::from_path(path).ok_or_else(|| Error::UnknownFormat { path: path.to_path_buf() })?;
    let mut points = match format {
        Format::Pcd => pcd::read(path)?,
        Format::Ply => ply::read(path)?,
        Format::Las => las::read(path)?,
        Format::Text => text::read(path)?,
    };
    let total = points.len();
    points.retain(|p| p.iter().all(|v| v.is_finite()));
    let non_finite = total - points.len();
    if points.is_empty() {
        let why = if total == 0 {
            "the file holds no points".to_owned()
        } else {
            format!("the file holds no finite point ({non_finite} with NaN or infinite coordinates)")
        };
        return Err(Error::invalid(path, why));
    }
    Ok(Cloud { points, non_finite })
}

/// Reads the finite points of a map file ([`read`] without the count of skipped points).
pub fn read_cloud(path: &Path) -> Result<Vec<[f64; 3]>, Error> {
    read(path).map(|c| c.points)
}

/// Writes points to a map file (for exchange and tests): PCD binary with `f64` fields, PLY binary
/// little endian with `double` properties, LAS 1.2 at millimetre resolution, or text with every digit.
pub fn write_cloud(path: &Path, points: &[[f64; 3]]) -> Result<(), Error> {
    match Format::from_path(path).ok_or_else(|| Error::UnknownFormat { path: path.to_path_buf() })? {
        Format::Pcd => pcd::write(path, points, pcd_rs::DataKind::Binary),
        Format::Ply => ply::write(path, points, PlyEncoding::BinaryLittleEndian),
        Format::Las => las::write(path, points),
        Format::Text => text::write(path, points),
    }
}

/// Writes a PLY file with the given encoding (the other writers have one natural encoding each).
pub fn write_ply(path: &Path, points: &[[f64; 3]], encoding: PlyEncoding) -> Result<(), Error> {
    ply::write(path, points, encoding)
}

/// Writes an ascii PCD file.
pub fn write_pcd_ascii(path: &Path, points: &[[f64; 3]]) -> Result<(), Error> {
    pcd::write(path, points, pcd_rs::DataKind::Ascii)
}
