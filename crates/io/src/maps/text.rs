//! Whitespace-separated text clouds: `x y z [more columns]` per line, `#` comments, blank lines.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;

use super::Error;

pub(crate) fn read(path: &Path) -> Result<Vec<[f64; 3]>, Error> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut points = Vec::new();
    for (i, line) in BufReader::new(file).lines().enumerate() {
        let line = line.map_err(|e| Error::invalid(path, format!("line {}: {e}", i + 1)))?;
        let content = line.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let mut xyz = [0.0; 3];
        let mut fields = content.split_whitespace();
        for (k, v) in xyz.iter_mut().enumerate() {
            let token = fields.next().ok_or_else(|| {
                Error::invalid(path, format!("line {}: {} columns, expected at least x y z", i + 1, k))
            })?;
            *v = token
                .parse()
                .map_err(|_| Error::invalid(path, format!("line {}: `{token}` is not a number", i + 1)))?;
        }
        points.push(xyz);
    }
    Ok(points)
}

pub(crate) fn write(path: &Path, points: &[[f64; 3]]) -> Result<(), Error> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut out = std::io::BufWriter::new(file);
    let mut go = || -> std::io::Result<()> {
        writeln!(out, "# x y z")?;
        for p in points {
            // `{}` prints the shortest decimal that reads back to the same f64.
            writeln!(out, "{} {} {}", p[0], p[1], p[2])?;
        }
        out.flush()
    };
    go().map_err(|e| Error::io(path, e))
}
