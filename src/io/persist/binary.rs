//! The little-endian binary pieces shared by checkpoints and shard files: numbers, strings, the
//! run counters and recorded LDH lines, written to a byte vector and read back by a reader that
//! fails (never panics) past the end or on a count larger than the bytes left.

use crate::detect::RecordedLine;
use crate::stats::RunStats;

/// Bytes per recorded line: `roi` (u32), `class` (u8), `weight`, `frequency`, `gamma` (f64).
const LINE_BYTES: u64 = 29;

/// Appends little-endian values to a byte vector.
pub(crate) struct Writer(pub Vec<u8>);

impl Writer {
    pub fn u64s(&mut self, values: &[u64]) {
        values.iter().for_each(|v| self.0.extend_from_slice(&v.to_le_bytes()));
    }

    pub fn f64s(&mut self, values: &[f64]) {
        values.iter().for_each(|v| self.0.extend_from_slice(&v.to_le_bytes()));
    }

    /// A UTF-8 string, after its length in bytes (u64).
    pub fn str(&mut self, s: &str) {
        self.u64s(&[s.len() as u64]);
        self.0.extend_from_slice(s.as_bytes());
    }

    /// The six run counters.
    pub fn stats(&mut self, st: &RunStats) {
        self.u64s(&[
            st.paths,
            st.scattering_events,
            st.null_collisions,
            st.roulette_terminations,
            st.truncated_paths,
            st.non_finite,
        ]);
    }

    /// Recorded lines, after their number (u64).
    pub fn lines(&mut self, lines: &[RecordedLine]) {
        self.u64s(&[lines.len() as u64]);
        for l in lines {
            self.0.extend_from_slice(&l.roi.to_le_bytes());
            self.0.push(l.class);
            self.f64s(&[l.weight, l.frequency, l.gamma]);
        }
    }
}

/// Reads little-endian values off a byte slice; `None` past the end.
pub(crate) struct Reader<'a>(pub &'a [u8]);

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, rest) = self.0.split_at_checked(N)?;
        self.0 = rest;
        head.try_into().ok()
    }

    pub fn u64(&mut self) -> Option<u64> {
        self.take::<8>().map(u64::from_le_bytes)
    }

    pub fn f64(&mut self) -> Option<f64> {
        self.take::<8>().map(f64::from_le_bytes)
    }

    /// Whether `n` items of `size` bytes can still be read: checked before allocating for them.
    fn holds(&self, n: u64, size: u64) -> bool {
        n.checked_mul(size).is_some_and(|b| b <= self.0.len() as u64)
    }

    pub fn f64s(&mut self, n: u64) -> Option<Vec<f64>> {
        if !self.holds(n, 8) {
            return None;
        }
        (0..n).map(|_| self.f64()).collect()
    }

    pub fn str(&mut self) -> Option<String> {
        let n = self.u64()?;
        if !self.holds(n, 1) {
            return None;
        }
        let (head, rest) = self.0.split_at(n as usize);
        self.0 = rest;
        String::from_utf8(head.to_vec()).ok()
    }

    pub fn stats(&mut self) -> Option<RunStats> {
        Some(RunStats {
            paths: self.u64()?,
            scattering_events: self.u64()?,
            null_collisions: self.u64()?,
            roulette_terminations: self.u64()?,
            truncated_paths: self.u64()?,
            non_finite: self.u64()?,
            work: Default::default(),
        })
    }

    pub fn lines(&mut self) -> Option<Vec<RecordedLine>> {
        let n = self.u64()?;
        if !self.holds(n, LINE_BYTES) {
            return None;
        }
        (0..n)
            .map(|_| {
                let roi = u32::from_le_bytes(self.take::<4>()?);
                let class = self.take::<1>()?[0];
                Some(RecordedLine { roi, class, weight: self.f64()?, frequency: self.f64()?, gamma: self.f64()? })
            })
            .collect()
    }

    /// Whether every byte was read.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}
