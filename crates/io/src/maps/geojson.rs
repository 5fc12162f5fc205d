//! The rows of a field as a GeoJSON FeatureCollection: one LineString per row, `[x, y]` in the cloud's
//! own frame and units, properties `index`, `spacing_m`, `support` (points), `length_m`.

use croprow_core::mapping::RowMap;
use serde_json::{Value, json};

/// The GeoJSON FeatureCollection of `map`, with the layout (`spacing_m`, `direction_rad`, the height
/// slice) repeated as foreign members of the collection.
pub fn rows_to_geojson(map: &RowMap) -> Value {
    let features: Vec<Value> = map
        .rows
        .iter()
        .map(|row| {
            json!({
                "type": "Feature",
                "geometry": { "type": "LineString", "coordinates": row.polyline },
                "properties": {
                    "index": row.index,
                    "spacing_m": map.spacing_m,
                    "support": row.support,
                    "length_m": row.length_m,
                },
            })
        })
        .collect();
    json!({
        "type": "FeatureCollection",
        "features": features,
        "spacing_m": map.spacing_m,
        "direction_rad": map.direction_rad,
        "height_slice_m": [map.slice.min_m, map.slice.max_m],
        "periodicity": map.slice.periodicity,
        "canopy_height_m": map.canopy_height_m,
    })
}
