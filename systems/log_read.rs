//! A recording read back with Rerun's own decoder: the frames each entity was logged at and
//! every sim_time (what the tests check a recording against).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

#[derive(Clone, Debug, Default)]
pub struct RecordingIndex {
    /// Entity path -> the `frame` times it was logged at (static data: none).
    pub frames: BTreeMap<String, BTreeSet<i64>>,
    /// Every `sim_time` logged (ns).
    pub sim_time: BTreeSet<i64>,
}

pub fn read_recording(path: &Path) -> Result<RecordingIndex, Box<dyn std::error::Error>> {
    let file = std::io::BufReader::new(std::fs::File::open(path)?);
    let decoder = rerun::external::re_log_encoding::DecoderApp::decode_eager(file)?;
    let mut index = RecordingIndex::default();
    for msg in decoder {
        if let rerun::log::LogMsg::ArrowMsg(_, arrow) = msg? {
            let chunk = rerun::log::Chunk::from_arrow_msg(&arrow)?;
            let entry = index.frames.entry(chunk.entity_path().to_string()).or_default();
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
