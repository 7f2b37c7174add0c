//! Shard files: `ohd run --shard I/N` writes every batch's tally sums of its part of a run to
//! `DIR/shard.ohd`, and `ohd merge` reads them back ([`crate::run::shard`]).
//!
//! Layout (little-endian): `OHDSHRD` and a format byte; the header as a block (its length, u64,
//! then: fingerprint, index, count, first and last batch, the run's batches, paths per batch,
//! tallies (u64 each); the configuration's text, where it came from and the `--set` list (strings
//! as length + UTF-8)); `(last − first) × tallies` f64 sums, batch by batch; the trailer as a
//! block (the six run counters (u64), wall seconds (f64), threads (u64), the recorded LDH lines);
//! the CRC-32 of everything before it (u32): a flipped byte is refused, not merged. The file is
//! written to a temporary name and renamed when whole.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use super::binary::{Reader, Writer};
use crate::detect::RecordedLine;
use crate::error::{Error, Result};
use crate::io::outdir::{OutDir, Temporary};
use crate::stats::RunStats;

const MAGIC: &[u8; 8] = b"OHDSHRD\x02";

/// The file a shard writes into its directory.
pub const FILE_NAME: &str = "shard.ohd";

/// Header blocks above this size are corrupt (it holds a configuration file's text).
const MAX_HEADER: u64 = 1 << 30;

/// Which part of which run a shard is.
#[derive(Debug, Clone, PartialEq)]
pub struct ShardHeader {
    /// Of the configuration as run, without `run.threads` ([`super::config_fingerprint`]).
    pub fingerprint: u64,
    /// This is part `index` of `count`, batches `first..last` of the run's `batches`.
    pub index: u64,
    pub count: u64,
    pub first: u64,
    pub last: u64,
    pub batches: u64,
    pub paths_per_batch: u64,
    /// Tally sums per batch.
    pub tallies: u64,
    /// The configuration as given: its text, where it came from (a file's absolute path, which
    /// relative media paths are resolved against) and the `--set` overrides.
    pub config_text: String,
    pub config_source: String,
    pub overrides: Vec<String>,
}

/// What a shard ends with: its counters, recorded lines (in batch order), time and threads.
#[derive(Debug, Clone, Default)]
pub struct ShardTrailer {
    pub stats: RunStats,
    pub seconds: f64,
    pub threads: u64,
    pub lines: Vec<RecordedLine>,
}

/// A block: its length (u64), then its bytes.
fn block(w: Writer) -> Vec<u8> {
    let mut b = (w.0.len() as u64).to_le_bytes().to_vec();
    b.extend(w.0);
    b
}

fn header_bytes(h: &ShardHeader) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    w.u64s(&[h.fingerprint, h.index, h.count, h.first, h.last, h.batches, h.paths_per_batch, h.tallies]);
    w.str(&h.config_text);
    w.str(&h.config_source);
    w.u64s(&[h.overrides.len() as u64]);
    h.overrides.iter().for_each(|s| w.str(s));
    block(w)
}

fn parse_header(bytes: &[u8]) -> Option<ShardHeader> {
    let mut r = Reader(bytes);
    let mut n = [0u64; 8];
    for v in &mut n {
        *v = r.u64()?;
    }
    let [fingerprint, index, count, first, last, batches, paths_per_batch, tallies] = n;
    let (config_text, config_source) = (r.str()?, r.str()?);
    let k = r.u64()?;
    let overrides = (0..k.min(bytes.len() as u64)).map(|_| r.str()).collect::<Option<Vec<_>>>()?;
    let whole = r.is_empty() && overrides.len() as u64 == k && index < count && first < last && last <= batches;
    whole.then_some(ShardHeader {
        fingerprint,
        index,
        count,
        first,
        last,
        batches,
        paths_per_batch,
        tallies,
        config_text,
        config_source,
        overrides,
    })
}

fn trailer_bytes(t: &ShardTrailer) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    w.stats(&t.stats);
    w.f64s(&[t.seconds]);
    w.u64s(&[t.threads]);
    w.lines(&t.lines);
    block(w)
}

fn parse_trailer(bytes: &[u8]) -> Option<ShardTrailer> {
    let mut r = Reader(bytes);
    let t = ShardTrailer { stats: r.stats()?, seconds: r.f64()?, threads: r.u64()?, lines: r.lines()? };
    r.is_empty().then_some(t)
}

/// Writes a shard file batch by batch (so a shard holds one batch's tallies in memory, not its
/// part's), to a temporary file that [`finish`](Self::finish) renames; dropped unfinished, the
/// temporary file is removed.
pub struct ShardWriter {
    file: BufWriter<File>,
    crc: crc32fast::Hasher,
    tmp: Temporary,
    path: PathBuf,
}

impl ShardWriter {
    /// A shard file `name` in `dir`.
    pub fn create(dir: &OutDir, name: &str, header: &ShardHeader) -> Result<Self> {
        let mut tmp = dir.temporary(name)?;
        let path = tmp.path().to_path_buf();
        let file = tmp.file().try_clone().map_err(|source| Error::Write { path: path.clone(), source })?;
        let mut w = ShardWriter { file: BufWriter::new(file), crc: crc32fast::Hasher::new(), tmp, path };
        w.put(MAGIC)?;
        w.put(&header_bytes(header))?;
        Ok(w)
    }

    fn put(&mut self, bytes: &[u8]) -> Result<()> {
        self.crc.update(bytes);
        self.file.write_all(bytes).map_err(|source| Error::Write { path: self.path.clone(), source })
    }

    /// Append the next batch's tally sums.
    pub fn batch(&mut self, sums: &[f64]) -> Result<()> {
        let bytes: Vec<u8> = sums.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.put(&bytes)
    }

    /// Append the trailer and move the whole file into place.
    pub fn finish(mut self, trailer: &ShardTrailer) -> Result<()> {
        self.put(&trailer_bytes(trailer))?;
        let crc = self.crc.clone().finalize();
        self.put(&crc.to_le_bytes())?;
        self.file.flush().map_err(|source| Error::Write { path: self.path.clone(), source })?;
        self.tmp.commit().map(drop)
    }
}

/// Reads a shard file: the header on [`open`](Self::open), then its batches one by one, then
/// the trailer. Every read is checked: a truncated, extended or corrupt file is an error naming it.
pub struct ShardReader {
    file: BufReader<File>,
    crc: crc32fast::Hasher,
    pub path: PathBuf,
    pub header: ShardHeader,
    batches_read: u64,
    /// Bytes left after the header.
    left: u64,
}

impl ShardReader {
    pub fn open(path: &Path) -> Result<Self> {
        let rerr = |source| Error::Read { path: path.to_path_buf(), source };
        let bad = |why: &str| Error::invalid_file(path, why);
        // Not a device or a FIFO (whose open or reads would not end): read as its size says.
        if !std::fs::metadata(path).map_err(rerr)?.is_file() {
            return Err(bad("not a regular file: expected an ohd shard file (written by `ohd run --shard I/N`)"));
        }
        let file = File::open(path).map_err(rerr)?;
        let meta = file.metadata().map_err(rerr)?;
        if !meta.is_file() {
            return Err(bad("not a regular file: expected an ohd shard file (written by `ohd run --shard I/N`)"));
        }
        let size = meta.len();
        let mut file = BufReader::new(file);
        let mut head = [0u8; 16];
        if size < 16 || file.read_exact(&mut head).is_err() || head[..7] != MAGIC[..7] {
            return Err(bad("not an ohd shard file (written by `ohd run --shard I/N`)"));
        }
        if head[7] != MAGIC[7] {
            return Err(bad("written by another version of ohd (shard format differs): rerun the shard"));
        }
        let len = u64::from_le_bytes(head[8..].try_into().unwrap_or_default());
        if len > MAX_HEADER.min(size - 16) {
            return Err(bad("truncated or corrupt shard file (header)"));
        }
        let mut bytes = vec![0; len as usize];
        file.read_exact(&mut bytes).map_err(rerr)?;
        let header = parse_header(&bytes).ok_or_else(|| bad("corrupt shard file (header)"))?;
        let mut crc = crc32fast::Hasher::new();
        crc.update(&head);
        crc.update(&bytes);
        // The sums and the trailer; the checksum's 4 bytes are not part of it.
        let left = (size - 16 - len).checked_sub(4).ok_or_else(|| bad("truncated shard file (no checksum)"))?;
        let sums = (header.last - header.first).checked_mul(header.tallies).and_then(|n| n.checked_mul(8));
        if sums.is_none_or(|n| n.saturating_add(8) > left) {
            return Err(bad("truncated shard file: fewer batches than its header names (was the shard killed?)"));
        }
        Ok(ShardReader { file, crc, path: path.to_path_buf(), header, batches_read: 0, left })
    }

    /// Read the next batch's sums into `sums` (`header.tallies` long).
    pub fn batch(&mut self, sums: &mut [f64]) -> Result<()> {
        let part = self.header.last - self.header.first;
        if self.batches_read == part || sums.len() as u64 != self.header.tallies {
            return Err(Error::invalid_file(&self.path, "read past the shard's batches"));
        }
        let mut bytes = vec![0u8; 8 * sums.len()];
        self.file.read_exact(&mut bytes).map_err(|source| Error::Read { path: self.path.clone(), source })?;
        self.crc.update(&bytes);
        for (v, b) in sums.iter_mut().zip(bytes.chunks_exact(8)) {
            *v = f64::from_le_bytes(b.try_into().unwrap_or_default());
        }
        if !sums.iter().all(|v| super::plausible(*v)) {
            let batch = self.header.first + self.batches_read;
            return Err(Error::invalid_file(
                &self.path,
                format!("batch {batch} holds a tally no run can produce (not finite, or beyond 1e100): corrupt"),
            ));
        }
        self.batches_read += 1;
        self.left -= bytes.len() as u64;
        Ok(())
    }

    /// The trailer, after every batch was read; the file must end there, with the checksum of
    /// everything read (an error naming the file if it differs: a corrupt shard is never merged).
    pub fn trailer(mut self) -> Result<ShardTrailer> {
        let bad = |why: &str| Error::invalid_file(&self.path, why);
        if self.batches_read != self.header.last - self.header.first {
            return Err(bad("the trailer was read before the batches"));
        }
        let mut len = [0u8; 8];
        self.file.read_exact(&mut len).map_err(|source| Error::Read { path: self.path.clone(), source })?;
        let len = u64::from_le_bytes(len);
        if len != self.left - 8 {
            return Err(bad("truncated or corrupt shard file (trailer)"));
        }
        let mut bytes = vec![0; len as usize];
        self.file.read_exact(&mut bytes).map_err(|source| Error::Read { path: self.path.clone(), source })?;
        let mut stored = [0u8; 4];
        self.file.read_exact(&mut stored).map_err(|source| Error::Read { path: self.path.clone(), source })?;
        let mut crc = self.crc.clone();
        crc.update(&len.to_le_bytes());
        crc.update(&bytes);
        if crc.finalize().to_le_bytes() != stored {
            return Err(bad("corrupt shard file (checksum mismatch): rerun the shard"));
        }
        parse_trailer(&bytes).ok_or_else(|| bad("corrupt shard file (trailer)"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> ShardHeader {
        ShardHeader {
            fingerprint: 7,
            index: 1,
            count: 3,
            first: 2,
            last: 4,
            batches: 6,
            paths_per_batch: 10,
            tallies: 3,
            config_text: "schema_version = 1\n".into(),
            config_source: "/x/y.toml".into(),
            overrides: vec!["run.seed=3".into(), "run.samples=60".into()],
        }
    }

    /// A shard file reads back as written; every truncation and an extra byte are errors.
    #[test]
    fn round_trip_and_corruption() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(FILE_NAME);
        let out = OutDir::create(dir.path()).unwrap();
        let mut w = ShardWriter::create(&out, FILE_NAME, &header()).unwrap();
        w.batch(&[1.0, 2.0, 3.0]).unwrap();
        w.batch(&[4.0, -0.5, 6.25]).unwrap();
        let t = ShardTrailer {
            stats: RunStats { paths: 20, scattering_events: 9, ..Default::default() },
            seconds: 1.25,
            threads: 2,
            lines: vec![RecordedLine { roi: 1, class: 2, weight: 0.5, frequency: -3.0, gamma: 1e-3 }],
        };
        w.finish(&t).unwrap();
        let read_all = |p: &Path| -> Result<(ShardHeader, Vec<Vec<f64>>, ShardTrailer)> {
            let mut r = ShardReader::open(p)?;
            let mut b = vec![vec![0.0; 3]; 2];
            for s in &mut b {
                r.batch(s)?;
            }
            let h = r.header.clone();
            Ok((h, b, r.trailer()?))
        };
        let (h, b, back) = read_all(&path).unwrap();
        assert_eq!(h, header());
        assert_eq!(b, vec![vec![1.0, 2.0, 3.0], vec![4.0, -0.5, 6.25]]);
        assert_eq!((back.stats, back.seconds, back.threads, back.lines), (t.stats, 1.25, 2, t.lines));
        let bytes = std::fs::read(&path).unwrap();
        let cut = dir.path().join("cut.ohd");
        for n in 0..bytes.len() {
            std::fs::write(&cut, &bytes[..n]).unwrap();
            assert!(read_all(&cut).is_err(), "a shard cut at {n} of {} bytes was read", bytes.len());
        }
        let mut longer = bytes.clone();
        longer.push(0);
        std::fs::write(&cut, &longer).unwrap();
        assert!(read_all(&cut).is_err(), "a shard with a trailing byte was read");
        // Any one flipped bit is caught (issue 21: a flipped data byte was merged).
        for i in 0..bytes.len() {
            let mut flipped = bytes.clone();
            flipped[i] ^= 1 << (i % 8);
            std::fs::write(&cut, &flipped).unwrap();
            assert!(read_all(&cut).is_err(), "a shard with byte {i} flipped was read");
        }
        drop(out);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2, "no temporary file or lock is left");
    }
}
