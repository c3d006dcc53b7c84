//! A recording read back with Rerun's own decoder: the frames each entity was logged at and
//! every sim_time (what the tests check a recording against).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use rerun::external::arrow::array::Array as _;

#[derive(Clone, Debug, Default)]
pub struct RecordingIndex {
    /// Entity path -> the `frame` times it was logged at (static data: none).
    pub frames: BTreeMap<String, BTreeSet<i64>>,
    /// Every `sim_time` logged (ns).
    pub sim_time: BTreeSet<i64>,
    /// The ids of the recordings in the file (their store infos; blueprints left out).
    pub recording_ids: BTreeSet<String>,
    /// Every text property: "entity:field" (under `/__properties`) -> its value.
    pub properties: BTreeMap<String, String>,
    /// Every numeric property: "entity:field" (under `/__properties`) -> its values (the
    /// colour scales).
    pub property_numbers: BTreeMap<String, Vec<f64>>,
    /// Entity path -> the vertex colours (RGBA, 0xRRGGBBAA) it was last logged with.
    pub colours: BTreeMap<String, Vec<u32>>,
    /// Every text of the blueprints sent (view names, origins, content queries).
    pub blueprint: BTreeSet<String>,
    /// Blueprint entity (`/view/<id>`, `/view/<id>/EyeControls3D`, ...) -> component -> its
    /// texts.
    pub blueprint_texts: BTreeMap<String, BTreeMap<String, Vec<String>>>,
    /// Blueprint entity -> component -> its numbers, flattened (an eye's position: 3 floats; a
    /// flag: 0 or 1).
    pub blueprint_numbers: BTreeMap<String, BTreeMap<String, Vec<f64>>>,
    /// Entity path -> the last text document logged to it (the colour legend).
    pub documents: BTreeMap<String, String>,
    /// Entity path -> the radii it was last logged with (negative: UI points, Rerun's encoding).
    pub radii: BTreeMap<String, Vec<f32>>,
}

pub fn read_recording(path: &Path) -> Result<RecordingIndex, Box<dyn std::error::Error>> {
    let file = std::io::BufReader::new(std::fs::File::open(path)?);
    let decoder = rerun::external::re_log_encoding::DecoderApp::decode_eager(file)?;
    let mut index = RecordingIndex::default();
    for msg in decoder {
        let msg = msg?;
        if let rerun::log::LogMsg::SetStoreInfo(info) = &msg {
            let id = &info.info.store_id;
            if id.kind() == rerun::StoreKind::Recording {
                index.recording_ids.insert(id.recording_id().to_string());
            }
        }
        if let rerun::log::LogMsg::ArrowMsg(store, arrow) = msg {
            let chunk = rerun::log::Chunk::from_arrow_msg(&arrow)?;
            if store.kind() == rerun::StoreKind::Blueprint {
                let entity = chunk.entity_path().to_string();
                for (field, column) in chunk.components().0.iter() {
                    let t = texts(&column.list_array);
                    index.blueprint.extend(t.iter().cloned());
                    let field = field.as_str().to_string();
                    if !t.is_empty() {
                        index.blueprint_texts.entry(entity.clone()).or_default().insert(field.clone(), t);
                    }
                    let n = floats(column.list_array.values().as_ref());
                    if !n.is_empty() {
                        index.blueprint_numbers.entry(entity.clone()).or_default().insert(field, n);
                    }
                }
                continue;
            }
            let entity = chunk.entity_path().to_string();
            if entity.starts_with("/__properties") {
                for (field, column) in chunk.components().0.iter() {
                    for v in texts(&column.list_array) {
                        index.properties.insert(format!("{entity}:{field}"), v);
                    }
                    let values = column.list_array.values();
                    let numbers = values.as_any().downcast_ref::<rerun::external::arrow::array::Float64Array>();
                    if let Some(n) = numbers.filter(|n| !n.is_empty()) {
                        index.property_numbers.insert(format!("{entity}:{field}"), n.values().to_vec());
                    }
                }
            }
            for (field, column) in chunk.components().0.iter() {
                let rows = &column.list_array;
                if field.as_str() == "TextDocument:text" {
                    if let Some(last) = texts(rows).pop() {
                        index.documents.insert(entity.clone(), last);
                    }
                }
                if field.as_str().ends_with(":radii") && !rows.is_empty() {
                    let last = rows.value(rows.len() - 1);
                    let r = last.as_any().downcast_ref::<rerun::external::arrow::array::Float32Array>();
                    if let Some(r) = r {
                        index.radii.insert(entity.clone(), r.values().to_vec());
                    }
                }
                if field.as_str().ends_with("vertex_colors") && !rows.is_empty() {
                    let last = rows.value(rows.len() - 1);
                    let rgba = last.as_any().downcast_ref::<rerun::external::arrow::array::UInt32Array>();
                    if let Some(rgba) = rgba {
                        index.colours.insert(entity.clone(), rgba.values().to_vec());
                    }
                }
            }
            let entry = index.frames.entry(entity).or_default();
            if let Some(col) = chunk.timelines().get(&"frame".into()) {
                entry.extend(col.times_raw().iter().copied());
            }
            if let Some(col) = chunk.timelines().get(&"sim_time".into()) {
                index.sim_time.extend(col.times_raw().iter().copied());
            }
        }
    }
    Ok(index)
}

/// The floats of an array, through fixed-size lists (a Position3D's three), booleans as 0 and
/// 1; none for others.
fn floats(values: &dyn rerun::external::arrow::array::Array) -> Vec<f64> {
    use rerun::external::arrow::array::{BooleanArray, FixedSizeListArray, Float32Array, Float64Array};
    let any = values.as_any();
    if let Some(b) = any.downcast_ref::<BooleanArray>() {
        b.iter().map(|x| f64::from(u8::from(x == Some(true)))).collect()
    } else if let Some(f) = any.downcast_ref::<Float32Array>() {
        f.values().iter().map(|x| f64::from(*x)).collect()
    } else if let Some(f) = any.downcast_ref::<Float64Array>() {
        f.values().to_vec()
    } else if let Some(l) = any.downcast_ref::<FixedSizeListArray>() {
        floats(l.values().as_ref())
    } else {
        vec![]
    }
}

/// The strings of a text component's column (none for other types).
fn texts(rows: &rerun::external::arrow::array::ListArray) -> Vec<String> {
    let values = rows.values();
    let text = values.as_any().downcast_ref::<rerun::external::arrow::array::StringArray>();
    text.into_iter().flat_map(|t| t.iter().flatten().map(str::to_string)).collect()
}
