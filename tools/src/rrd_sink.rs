//! The recording's file writer. Rerun's own `FileSink` ends its writer thread at the first write
//! error and every later message then blocks on the thread's full queue: a run whose disk filled
//! up never ended after frame 1 (issue 66). This sink writes in the logging thread, keeps the
//! first error for the run to report (`RrdFile::error`), and drops what comes after it.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use rerun::external::re_log_encoding::{CrateVersion, Encoder, EncodingOptions};
use rerun::log::LogMsg;
use rerun::sink::{LogSink, SinkFlushError};

struct State {
    /// None once finished or failed.
    encoder: Option<Encoder<BufWriter<File>>>,
    error: Option<String>,
}

/// A handle on the file the sink writes: its first error, and the end of its stream.
#[derive(Clone)]
pub struct RrdFile {
    path: PathBuf,
    state: Arc<Mutex<State>>,
}

/// The `LogSink` that writes `RrdFile`.
pub struct RrdSink(RrdFile);

impl RrdFile {
    /// Creates `path` (truncating it) and writes the stream's header.
    pub fn create(path: &Path) -> Result<(RrdFile, RrdSink), String> {
        let file = File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::start(path, file)
    }

    /// The recording `path` continued after its first `len` bytes (a checkpoint's mark): those
    /// are decoded and written again, as the start of one new stream (so that its footer's
    /// manifest covers the whole file), into a file that then replaces `path`; what comes next
    /// is appended to it. Until the rename the old file stands whole.
    pub fn append(path: &Path, len: u64) -> Result<(RrdFile, RrdSink), String> {
        use std::io::Read;
        let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
        let old = File::open(path).map_err(|e| fail(&e))?;
        let on_disk = old.metadata().map_err(|e| fail(&e))?.len();
        if on_disk < len {
            return Err(format!("{}: {on_disk} bytes, shorter than the checkpoint's {len}", path.display()));
        }
        let fresh = path.with_extension("rrd.resume");
        let file = File::create(&fresh).map_err(|e| format!("{}: {e}", fresh.display()))?;
        let (rrd, sink) = Self::start(path, file)?;
        {
            let prefix = std::io::BufReader::new(old.take(len));
            let decoder = rerun::external::re_log_encoding::DecoderApp::decode_eager(prefix).map_err(|e| fail(&e))?;
            let mut s = rrd.lock();
            let encoder = s.encoder.as_mut().expect("a new encoder");
            for msg in decoder {
                let msg = msg.map_err(|e| fail(&e))?;
                encoder.append(&msg).map_err(|e| format!("{}: {e}", fresh.display()))?;
            }
            encoder.flush_blocking().map_err(|e| format!("{}: {e}", fresh.display()))?;
        }
        std::fs::rename(&fresh, path).map_err(|e| fail(&e))?;
        Ok((rrd, sink))
    }

    fn start(path: &Path, file: File) -> Result<(RrdFile, RrdSink), String> {
        let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
        let encoder =
            Encoder::new_eager(CrateVersion::LOCAL, EncodingOptions::PROTOBUF_COMPRESSED, BufWriter::new(file))
                .map_err(|e| fail(&e))?;
        let state = Arc::new(Mutex::new(State { encoder: Some(encoder), error: None }));
        let file = RrdFile { path: path.to_path_buf(), state };
        Ok((file.clone(), RrdSink(file)))
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The first write error, naming the file.
    pub fn error(&self) -> Option<String> {
        self.lock().error.clone()
    }

    /// Ends the stream (its footer, then a flush): what the viewer needs to read the file to its
    /// end. Messages sent after it are dropped. Returns the first error of the whole file.
    pub fn finish(&self) -> Result<(), String> {
        let mut s = self.lock();
        if let Some(mut e) = s.encoder.take() {
            if let Err(err) = e.finish().and_then(|_| e.flush_blocking()) {
                s.error.get_or_insert(format!("{}: {err}", self.path.display()));
            }
        }
        s.error.clone().map_or(Ok(()), Err)
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // (a panic while holding it leaves the state as it was: still usable)
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn record(&self, s: &mut State, err: impl std::fmt::Display) {
        s.error.get_or_insert(format!("{}: {err}", self.path.display()));
        s.encoder = None;
    }
}

impl LogSink for RrdSink {
    fn send(&self, msg: LogMsg) {
        let mut s = self.0.lock();
        if let Some(e) = s.encoder.as_mut() {
            if let Err(err) = e.append(&msg) {
                self.0.record(&mut s, err);
            }
        }
    }

    fn flush_blocking(&self, _timeout: Duration) -> Result<(), SinkFlushError> {
        let mut s = self.0.lock();
        if let Some(e) = s.encoder.as_mut() {
            if let Err(err) = e.flush_blocking() {
                self.0.record(&mut s, err);
            }
        }
        match &s.error {
            Some(message) => Err(SinkFlushError::Failed { message: message.clone() }),
            None => Ok(()),
        }
    }

    fn defers_finalization_to_shutdown(&self) -> bool {
        true
    }
}

impl Drop for RrdSink {
    fn drop(&mut self) {
        let _ = self.0.finish();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_disk_is_reported_and_nothing_blocks() {
        // /dev/full takes the header into its buffer, then fails every write with ENOSPC.
        let Ok((file, sink)) = RrdFile::create(Path::new("/dev/full")) else { return };
        let rec = rerun::RecordingStreamBuilder::new("t")
            .set_sinks(vec![Box::new(sink) as Box<dyn rerun::sink::LogSink>])
            .unwrap();
        for i in 0..200 {
            rec.log(format!("p/{i}"), &rerun::Points3D::new([[0.0f32; 3]; 1000])).unwrap();
        }
        let _ = rec.flush_blocking();
        let e = file.error().expect("an error");
        assert!(e.starts_with("/dev/full: ") && e.contains("space"), "{e}");
        assert!(file.finish().is_err());
    }

    #[test]
    fn a_written_file_reads_back() {
        let d = std::env::temp_dir().join(format!("skinsim-rrd-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let path = d.join("r.rrd");
        let (file, sink) = RrdFile::create(&path).unwrap();
        let rec = rerun::RecordingStreamBuilder::new("t")
            .set_sinks(vec![Box::new(sink) as Box<dyn rerun::sink::LogSink>])
            .unwrap();
        rec.set_time_sequence("frame", 3);
        rec.log("p", &rerun::Points3D::new([[0.0f32; 3]])).unwrap();
        rec.flush_blocking().unwrap();
        file.finish().unwrap();
        let index = skinsim_systems::log_read::read_recording(&path).unwrap();
        assert_eq!(index.frames["/p"].iter().copied().collect::<Vec<_>>(), [3]);
    }
}
