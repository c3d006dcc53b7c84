//! The stage's spool: each time-sampled attribute of each prim in a file of its own, one record
//! per frame (the frame, the number of 4-byte words, the words little-endian), so that no frame
//! is held in memory before the stage is written.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::Path;

/// One attribute's samples, appended frame by frame, and the bytes written so far.
pub(super) struct SpoolWriter(BufWriter<File>, u64);

impl SpoolWriter {
    pub(super) fn create(path: &Path) -> std::io::Result<Self> {
        Ok(SpoolWriter(BufWriter::new(File::create(path)?), 0))
    }

    /// The spool `path` cut back to its first `len` bytes (a checkpoint's mark), to append to.
    pub(super) fn reopen(path: &Path, len: u64) -> std::io::Result<Self> {
        let file = std::fs::OpenOptions::new().write(true).open(path)?;
        if file.metadata()?.len() < len {
            return Err(std::io::Error::other(format!("{} is shorter than its checkpoint's mark", path.display())));
        }
        file.set_len(len)?;
        let mut w = BufWriter::new(file);
        std::io::Seek::seek(&mut w, std::io::SeekFrom::Start(len))?;
        Ok(SpoolWriter(w, len))
    }

    /// The bytes written so far.
    pub(super) fn len(&self) -> u64 {
        self.1
    }

    /// Appends the sample of `frame`: `words` as 4-byte little-endian words.
    pub(super) fn floats(&mut self, frame: u32, words: impl ExactSizeIterator<Item = f32>) -> std::io::Result<()> {
        self.header(frame, words.len())?;
        for x in words {
            self.0.write_all(&x.to_le_bytes())?;
            self.1 += 4;
        }
        Ok(())
    }

    pub(super) fn ints(&mut self, frame: u32, words: impl ExactSizeIterator<Item = i32>) -> std::io::Result<()> {
        self.header(frame, words.len())?;
        for x in words {
            self.0.write_all(&x.to_le_bytes())?;
            self.1 += 4;
        }
        Ok(())
    }

    fn header(&mut self, frame: u32, len: usize) -> std::io::Result<()> {
        let len = u32::try_from(len).map_err(|_| std::io::Error::other("a sample of over 2^32 values"))?;
        self.0.write_all(&frame.to_le_bytes())?;
        self.0.write_all(&len.to_le_bytes())?;
        self.1 += 8;
        Ok(())
    }

    pub(super) fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

/// Reads an attribute's samples back in the order written.
pub(super) struct SpoolReader(BufReader<File>);

impl SpoolReader {
    pub(super) fn open(path: &Path) -> std::io::Result<Self> {
        Ok(SpoolReader(BufReader::new(File::open(path)?)))
    }

    /// The next sample: its frame and its words; None at the end.
    pub(super) fn next_words(&mut self) -> std::io::Result<Option<(u32, Vec<[u8; 4]>)>> {
        let mut head = [0u8; 8];
        match self.0.read_exact(&mut head) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(None),
            Err(e) => return Err(e),
        }
        let frame = u32::from_le_bytes(head[..4].try_into().expect("4 bytes"));
        let len = u32::from_le_bytes(head[4..].try_into().expect("4 bytes")) as usize;
        let mut bytes = vec![0u8; 4 * len];
        self.0.read_exact(&mut bytes)?;
        Ok(Some((frame, bytes.chunks_exact(4).map(|c| c.try_into().expect("4 bytes")).collect())))
    }

    pub(super) fn next_floats(&mut self) -> std::io::Result<Option<(u32, Vec<f32>)>> {
        Ok(self.next_words()?.map(|(f, w)| (f, w.into_iter().map(f32::from_le_bytes).collect())))
    }

    pub(super) fn next_ints(&mut self) -> std::io::Result<Option<(u32, Vec<i32>)>> {
        Ok(self.next_words()?.map(|(f, w)| (f, w.into_iter().map(i32::from_le_bytes).collect())))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_read_back_as_written() {
        let dir = std::env::temp_dir().join(format!("skinsim-spool-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a");
        let mut w = SpoolWriter::create(&path).unwrap();
        w.floats(0, [1.5f32, -2.0, f32::MAX].into_iter()).unwrap();
        w.ints(7, [3, -1].into_iter()).unwrap();
        w.floats(8, std::iter::empty::<f32>()).unwrap();
        w.flush().unwrap();
        let mut r = SpoolReader::open(&path).unwrap();
        assert_eq!(r.next_floats().unwrap(), Some((0, vec![1.5, -2.0, f32::MAX])));
        assert_eq!(r.next_ints().unwrap(), Some((7, vec![3, -1])));
        assert_eq!(r.next_floats().unwrap(), Some((8, vec![])));
        assert_eq!(r.next_floats().unwrap(), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
