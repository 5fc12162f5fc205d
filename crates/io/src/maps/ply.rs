//! Stanford PLY, read by a small header parser of our own (`ply-rs` is unmaintained): ascii, binary
//! little and big endian; the `vertex` element's `x`, `y`, `z` found by name in any order and of any
//! scalar type, among any other properties (lists included) and elements before or after it.

use std::io::Write;
use std::path::Path;

use super::Error;

/// How the data section of a PLY file is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// Whitespace-separated numbers.
    Ascii,
    /// Packed little-endian binary.
    BinaryLittleEndian,
    /// Packed big-endian binary.
    BinaryBigEndian,
}

/// A scalar type of the PLY header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// Decodes one value from exactly `size()` bytes.
    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(b);
                f64::from(if big { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) })
            }};
        }
        match self {
            Self::I8 => num!(i8, 1),
            Self::U8 => num!(u8, 1),
            Self::I16 => num!(i16, 2),
            Self::U16 => num!(u16, 2),
            Self::I32 => num!(i32, 4),
            Self::U32 => num!(u32, 4),
            Self::F32 => num!(f32, 4),
            Self::F64 => num!(f64, 8),
        }
    }
}

#[derive(Debug, Clone)]
enum Property {
    Scalar { name: String, kind: Scalar },
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the data section.
    data_start: usize,
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header, Error> {
    let bad = |problem: String| Error::invalid(path, format!("PLY header: {problem}"));
    let end = find(bytes, b"end_header")
        .ok_or_else(|| bad("no `end_header` (not a PLY file, or truncated)".into()))?;
    let mut data_start = end + b"end_header".len();
    // The header ends with a newline (`\n`, or `\r\n` from some writers).
    if bytes.get(data_start) == Some(&b'\r') {
        data_start += 1;
    }
    if bytes.get(data_start) == Some(&b'\n') {
        data_start += 1;
    }
    let text = std::str::from_utf8(&bytes[..end]).map_err(|_| bad("not ASCII text".into()))?;
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    if lines.next() != Some("ply") {
        return Err(bad("the file does not start with `ply`".into()));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    for (n, line) in lines.enumerate() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let at = |what: &str| bad(format!("line {}: {what}: `{line}`", n + 2));
        match words.as_slice() {
            ["comment", ..] | ["obj_info", ..] => {}
            ["format", kind, "1.0"] => {
                encoding = Some(match *kind {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    _ => return Err(at("unknown format")),
                })
            }
            ["element", name, count] => {
                let count = count.parse().map_err(|_| at("bad element count"))?;
                elements.push(Element { name: (*name).to_string(), count, properties: Vec::new() });
            }
            ["property", "list", count, item, _name] => {
                let count = Scalar::parse(count).ok_or_else(|| at("unknown list count type"))?;
                let item = Scalar::parse(item).ok_or_else(|| at("unknown list item type"))?;
                elements
                    .last_mut()
                    .ok_or_else(|| at("property before any element"))?
                    .properties
                    .push(Property::List { count, item });
            }
            ["property", kind, name] => {
                let kind = Scalar::parse(kind).ok_or_else(|| at("unknown property type"))?;
                elements
                    .last_mut()
                    .ok_or_else(|| at("property before any element"))?
                    .properties
                    .push(Property::Scalar { name: (*name).to_string(), kind });
            }
            _ => return Err(at("unrecognised header line")),
        }
    }
    let encoding = encoding.ok_or_else(|| bad("no `format` line".into()))?;
    Ok(Header { encoding, elements, data_start })
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

pub(crate) fn read(path: &Path) -> Result<Vec<[f64; 3]>, Error> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let header = parse_header(path, &bytes)?;
    let data = &bytes[header.data_start..];
    let vertex = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| Error::invalid(path, "PLY header: no `vertex` element"))?;
    let column = |name: &str| {
        header.elements[vertex]
            .properties
            .iter()
            .position(|p| matches!(p, Property::Scalar { name: n, .. } if n == name))
            .ok_or_else(|| {
                Error::invalid(path, format!("PLY header: the vertex element has no `{name}` property"))
            })
    };
    let xyz = [column("x")?, column("y")?, column("z")?];
    match header.encoding {
        Encoding::Ascii => read_ascii(path, data, &header.elements[..=vertex], xyz),
        enc => read_binary(path, data, &header.elements[..=vertex], xyz, enc == Encoding::BinaryBigEndian),
    }
}

/// Reads the elements up to and including the vertices (the last of `elements`); returns the vertices.
fn read_binary(
    path: &Path,
    data: &[u8],
    elements: &[Element],
    xyz: [usize; 3],
    big: bool,
) -> Result<Vec<[f64; 3]>, Error> {
    let mut at = 0usize;
    let truncated = |what: &str, i: usize| Error::invalid(path, format!("PLY data truncated in {what} {i}"));
    let mut take = |n: usize| -> Option<&[u8]> {
        let s = data.get(at..at + n)?;
        at += n;
        Some(s)
    };
    let mut points = Vec::new();
    let mut values = Vec::new();
    for (e, element) in elements.iter().enumerate() {
        let is_vertex = e + 1 == elements.len();
        if is_vertex {
            // Each vertex takes at least one byte: a count beyond the data is a lie, not an allocation.
            points.reserve(element.count.min(data.len()));
        }
        if element.properties.is_empty() {
            continue;
        }
        for i in 0..element.count {
            values.clear();
            for property in &element.properties {
                match *property {
                    Property::Scalar { kind, .. } => {
                        let b = take(kind.size()).ok_or_else(|| truncated(&element.name, i))?;
                        values.push(kind.decode(b, big));
                    }
                    Property::List { count, item } => {
                        let b = take(count.size()).ok_or_else(|| truncated(&element.name, i))?;
                        let n = count.decode(b, big);
                        if !(0.0..=1e6).contains(&n) {
                            return Err(Error::invalid(
                                path,
                                format!("PLY {} {i}: list length {n}", element.name),
                            ));
                        }
                        take(n as usize * item.size()).ok_or_else(|| truncated(&element.name, i))?;
                        values.push(f64::NAN);
                    }
                }
            }
            if is_vertex {
                points.push([values[xyz[0]], values[xyz[1]], values[xyz[2]]]);
            }
        }
    }
    Ok(points)
}

fn read_ascii(
    path: &Path,
    data: &[u8],
    elements: &[Element],
    xyz: [usize; 3],
) -> Result<Vec<[f64; 3]>, Error> {
    let text = std::str::from_utf8(data).map_err(|_| Error::invalid(path, "PLY ascii data is not text"))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let mut points = Vec::new();
    for (e, element) in elements.iter().enumerate() {
        let is_vertex = e + 1 == elements.len();
        if element.properties.is_empty() {
            continue;
        }
        for i in 0..element.count {
            let line = lines
                .next()
                .ok_or_else(|| Error::invalid(path, format!("PLY data truncated in {} {i}", element.name)))?;
            let tokens: Vec<&str> = line.split_whitespace().collect();
            if !is_vertex {
                continue;
            }
            let mut values = Vec::with_capacity(element.properties.len());
            let mut t = 0;
            for property in &element.properties {
                let token = *tokens.get(t).ok_or_else(|| {
                    Error::invalid(path, format!("PLY vertex {i}: too few values on `{line}`"))
                })?;
                let v: f64 = token.parse().map_err(|_| {
                    Error::invalid(path, format!("PLY vertex {i}: `{token}` is not a number"))
                })?;
                match property {
                    Property::Scalar { .. } => t += 1,
                    Property::List { .. } => {
                        // The count is followed by that many items on the same line: anything but a
                        // whole number that fits the line is a lie (and must not overflow `t`).
                        let items = tokens.len() - t - 1;
                        if !(v >= 0.0 && v.fract() == 0.0 && v <= items as f64) {
                            return Err(Error::invalid(
                                path,
                                format!("PLY vertex {i}: list length `{token}` with {items} values after it"),
                            ));
                        }
                        t += 1 + v as usize;
                    }
                }
                values.push(v);
            }
            points.push([values[xyz[0]], values[xyz[1]], values[xyz[2]]]);
        }
    }
    Ok(points)
}

pub(crate) fn write(path: &Path, points: &[[f64; 3]], encoding: Encoding) -> Result<(), Error> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut out = std::io::BufWriter::new(file);
    let format = match encoding {
        Encoding::Ascii => "ascii",
        Encoding::BinaryLittleEndian => "binary_little_endian",
        Encoding::BinaryBigEndian => "binary_big_endian",
    };
    let mut go = || -> std::io::Result<()> {
        write!(
            out,
            "ply\nformat {format} 1.0\ncomment written by croprow\nelement vertex {}\n",
            points.len()
        )?;
        write!(out, "property double x\nproperty double y\nproperty double z\nend_header\n")?;
        for p in points {
            match encoding {
                Encoding::Ascii => writeln!(out, "{} {} {}", p[0], p[1], p[2])?,
                Encoding::BinaryLittleEndian => p.iter().try_for_each(|v| out.write_all(&v.to_le_bytes()))?,
                Encoding::BinaryBigEndian => p.iter().try_for_each(|v| out.write_all(&v.to_be_bytes()))?,
            }
        }
        out.flush()
    };
    go().map_err(|e| Error::io(path, e))
}
