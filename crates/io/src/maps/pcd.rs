//! PCL's PCD through `pcd-rs` (ascii and binary): the x, y, z fields are found by name, in any order
//! and of any numeric type, among any others.

use std::path::Path;

use ::pcd_rs::{DataKind, DynReader, DynRecord, DynWriter, Field, Schema, ValueKind, WriterInit};

use super::Error;

pub(crate) fn read(path: &Path) -> Result<Vec<[f64; 3]>, Error> {
    let reader = DynReader::open(path).map_err(|e| Error::invalid(path, format!("PCD: {e}")))?;
    let fields = &reader.meta().field_defs;
    let column = |name: &str| {
        fields
            .iter()
            .position(|f| f.name == name)
            .ok_or_else(|| Error::invalid(path, format!("PCD: no `{name}` field")))
    };
    let (ix, iy, iz) = (column("x")?, column("y")?, column("z")?);
    let mut points = Vec::new();
    for record in reader {
        let DynRecord(values) =
            record.map_err(|e| Error::invalid(path, format!("PCD point {}: {e}", points.len())))?;
        let get = |i: usize| values.get(i).and_then(scalar);
        match (get(ix), get(iy), get(iz)) {
            (Some(x), Some(y), Some(z)) => points.push([x, y, z]),
            _ => {
                return Err(Error::invalid(
                    path,
                    format!("PCD point {}: x, y, z are not scalars", points.len()),
                ));
            }
        }
    }
    Ok(points)
}

/// The value of a one-element field as `f64`.
fn scalar(field: &Field) -> Option<f64> {
    match field {
        Field::I8(v) => v.first().map(|x| f64::from(*x)),
        Field::I16(v) => v.first().map(|x| f64::from(*x)),
        Field::I32(v) => v.first().map(|x| f64::from(*x)),
        Field::I64(v) => v.first().map(|x| *x as f64),
        Field::U8(v) => v.first().map(|x| f64::from(*x)),
        Field::U16(v) => v.first().map(|x| f64::from(*x)),
        Field::U32(v) => v.first().map(|x| f64::from(*x)),
        Field::U64(v) => v.first().map(|x| *x as f64),
        Field::F32(v) => v.first().map(|x| f64::from(*x)),
        Field::F64(v) => v.first().copied(),
    }
}

pub(crate) fn write(path: &Path, points: &[[f64; 3]], data_kind: DataKind) -> Result<(), Error> {
    let schema =
        Schema::from_iter([("x", ValueKind::F64, 1), ("y", ValueKind::F64, 1), ("z", ValueKind::F64, 1)]);
    let init = WriterInit {
        width: points.len() as u64,
        height: 1,
        viewpoint: Default::default(),
        data_kind,
        schema: Some(schema),
        version: None,
    };
    let fail = |e: ::pcd_rs::Error| Error::invalid(path, format!("PCD: {e}"));
    let mut writer: DynWriter<_> = init.create(path).map_err(fail)?;
    for p in points {
        writer
            .push(&DynRecord(vec![Field::F64(vec![p[0]]), Field::F64(vec![p[1]]), Field::F64(vec![p[2]])]))
            .map_err(fail)?;
    }
    writer.finish().map_err(fail)
}
