//! ASPRS LAS through the `las` crate, read in chunks so a header that lies about its point count
//! or its record length cannot make us allocate for it.

use std::path::Path;

use super::Error;

/// Bytes read per chunk: 64 Ki points of a typical 20-34 byte record. The chunk is sized in bytes,
/// not points, because the record length is a header field too (up to 64 KiB: a fixed point count
/// would let a corrupt header ask for 4 GiB).
const CHUNK_BYTES: usize = 2 << 20;

pub(crate) fn read(path: &Path) -> Result<Vec<[f64; 3]>, Error> {
    let mut reader = ::las::Reader::from_path(path).map_err(|e| Error::invalid(path, format!("LAS: {e}")))?;
    let expected = reader.header().number_of_points();
    let mut data = ::las::PointDataBuilder::new().for_header(reader.header()).build();
    let chunk = (CHUNK_BYTES / data.record_len().max(1)).max(1) as u64;
    let mut points = Vec::new();
    loop {
        let n = reader
            .fill_points(chunk, &mut data)
            .map_err(|e| Error::invalid(path, format!("LAS point {}: {e}", points.len())))?;
        if n == 0 {
            break;
        }
        for p in data.points() {
            let p = p.map_err(|e| Error::invalid(path, format!("LAS point {}: {e}", points.len())))?;
            points.push([p.x, p.y, p.z]);
        }
    }
    if (points.len() as u64) < expected {
        return Err(Error::invalid(
            path,
            format!("truncated: the header announces {expected} points, the file holds {}", points.len()),
        ));
    }
    Ok(points)
}

pub(crate) fn write(path: &Path, points: &[[f64; 3]]) -> Result<(), Error> {
    let mut builder = ::las::Builder::from((1, 2));
    let origin = points.first().copied().unwrap_or([0.0; 3]);
    let t = |o: f64| ::las::Transform { scale: 0.001, offset: o.round() };
    builder.transforms = ::las::Vector { x: t(origin[0]), y: t(origin[1]), z: t(origin[2]) };
    let header = builder.into_header().map_err(|e| Error::invalid(path, format!("LAS header: {e}")))?;
    let mut writer =
        ::las::Writer::from_path(path, header).map_err(|e| Error::invalid(path, format!("LAS: {e}")))?;
    for p in points {
        let point = ::las::Point { x: p[0], y: p[1], z: p[2], ..Default::default() };
        writer.write_point(point).map_err(|e| Error::invalid(path, format!("LAS: {e}")))?;
    }
    writer.close().map_err(|e| Error::invalid(path, format!("LAS: {e}")))
}
