//! NumPy `.npy`: written as format 1.0, little-endian `f64` in C order ([`to_bytes`]); read as
//! any format version of little-endian `f4`/`f8` arrays in C or Fortran order ([`read_floats`];
//! the density and velocity volumes of a scene, `density = { type = "npy", … }`, through
//! [`open_volume`], which reads the header alone so that what the data will take is counted
//! against the memory budget before any of it is read).

/// The bytes of a `.npy` file holding `data` with the given `shape`.
pub fn to_bytes(shape: &[usize], data: &[f64]) -> Vec<u8> {
    assert_eq!(shape.iter().product::<usize>(), data.len(), "npy shape does not match data");
    let dims = match shape {
        [n] => format!("({n},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {dims}, }}");
    // Magic (6) + version (2) + header length (2) + header + '\n', padded to a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 8 * data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Read back a `.npy` written by [`to_bytes`] (for tests and tools): shape and data.
pub fn from_bytes(bytes: &[u8]) -> Option<(Vec<usize>, Vec<f64>)> {
    if bytes.len() < 10 || &bytes[..8] != b"\x93NUMPY\x01\x00" {
        return None;
    }
    let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(bytes.get(10..10 + hlen)?).ok()?;
    if !header.contains("'descr': '<f8'") || !header.contains("'fortran_order': False") {
        return None;
    }
    let dims = header.split("'shape': (").nth(1)?.split(')').next()?;
    let shape: Vec<usize> =
        dims.split(',').map(str::trim).filter(|s| !s.is_empty()).map(|s| s.parse().ok()).collect::<Option<_>>()?;
    let body = &bytes[10 + hlen..];
    if body.len() != 8 * shape.iter().product::<usize>() {
        return None;
    }
    Some((shape, body.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect()))
}

/// A `.npy` array of floats read whole: its shape and its values as `f32`, in C order (the last
/// index fastest), whatever the file's order.
#[derive(Debug, Clone, PartialEq)]
pub struct FloatArray {
    pub shape: Vec<usize>,
    pub values: Vec<f32>,
}

/// What a `.npy` header says of the array after it.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    pub shape: Vec<usize>,
    /// Stored with the first index fastest.
    pub fortran: bool,
    /// Bytes per value: 4 (`<f4`) or 8 (`<f8`).
    pub item: usize,
    /// Values: the product of `shape`.
    pub count: usize,
    /// Bytes of the data: `count · item`, checked not to overflow.
    pub data_bytes: u64,
    /// Where the data starts: the magic, version, header length and header.
    pub offset: usize,
}

/// Longest header read from a file, bytes (NumPy itself refuses headers above 10,000 bytes).
pub const MAX_HEADER_BYTES: usize = 1 << 20;

/// The header of a `.npy` file from its first bytes (at least up to the end of the header):
/// format 1.0, 2.0 or 3.0, little-endian 32- or 64-bit floats (`<f4`, `<f8`) in C or Fortran
/// order, a shape whose size and byte count do not overflow. An error says what the file holds
/// instead, in words (a NumPy user reads `descr` `'<i8'` as "int64").
pub fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy file (no \\x93NUMPY magic)".into());
    }
    let (start, n) = match bytes[6] {
        1 => (10, u16::from_le_bytes([bytes[8], bytes[9]]) as usize),
        2 | 3 if bytes.len() >= 12 => (12, u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize),
        v => return Err(format!(".npy format version {v}: expected 1, 2 or 3")),
    };
    if n > MAX_HEADER_BYTES {
        return Err(format!("a .npy header of {n} bytes: expected at most {MAX_HEADER_BYTES}"));
    }
    let Some(header) = bytes.get(start..start + n) else { return Err("the .npy header is cut short".into()) };
    let header = std::str::from_utf8(header).map_err(|_| "the .npy header is not text".to_string())?;
    let field = |key: &str| -> Option<&str> {
        let rest = header.split(&format!("'{key}':")).nth(1)?.trim_start();
        Some(rest)
    };
    let descr = field("descr").and_then(|r| r.strip_prefix('\'')).and_then(|r| r.split('\'').next());
    let item = match descr {
        Some("<f4") => 4,
        Some("<f8") => 8,
        Some(other) => {
            return Err(format!(
                "dtype '{other}': expected little-endian float32 or float64 ('<f4' or '<f8'; convert with .astype(np.float32))"
            ));
        }
        None => return Err("the .npy header has no 'descr'".into()),
    };
    let fortran = match field("fortran_order") {
        Some(r) if r.starts_with("True") => true,
        Some(r) if r.starts_with("False") => false,
        _ => return Err("the .npy header has no 'fortran_order'".into()),
    };
    let dims = field("shape")
        .and_then(|r| r.strip_prefix('('))
        .and_then(|r| r.split(')').next())
        .ok_or_else(|| "the .npy header has no 'shape'".to_string())?;
    let shape: Vec<usize> = dims
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.trim_end_matches('L').parse::<usize>().map_err(|_| format!("shape entry {s:?} is not a size")))
        .collect::<Result<_, _>>()?;
    let overflow = || format!("shape {shape:?}: its size overflows");
    let count = shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d)).ok_or_else(overflow)?;
    let data_bytes = (count as u64).checked_mul(item as u64).ok_or_else(overflow)?;
    Ok(Header { shape, fortran, item, count, data_bytes, offset: start + n })
}

/// Read the bytes of a `.npy` file (format 1.0, 2.0 or 3.0) holding little-endian 32- or 64-bit
/// floats (`<f4`, `<f8`) in C or Fortran order ([`parse_header`]).
pub fn read_floats(bytes: &[u8]) -> Result<FloatArray, String> {
    let h = parse_header(bytes)?;
    let body = &bytes[h.offset..];
    if body.len() as u64 != h.data_bytes {
        return Err(format!(
            "{} bytes of data for shape {:?} of {}-byte floats: expected {}",
            body.len(),
            h.shape,
            h.item,
            h.data_bytes
        ));
    }
    let stored: Vec<f32> = if h.item == 4 {
        body.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
    } else {
        body.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])) as f32).collect()
    };
    let values = if h.fortran && h.shape.len() > 1 { fortran_to_c(&h.shape, &stored) } else { stored };
    Ok(FloatArray { shape: h.shape, values })
}

/// A `.npy` volume file opened and its header read, nothing of its data yet: the data are
/// read by [`Volume::for_each`] after the caller has counted what they will take.
pub struct Volume {
    pub header: Header,
    file: std::fs::File,
    path: std::path::PathBuf,
}

/// Open the `.npy` file `path`, a regular file whose length is its header's plus the data its
/// header's shape declares, and read its header (at most [`MAX_HEADER_BYTES`]).
pub fn open_volume(path: &std::path::Path) -> Result<Volume, String> {
    use std::io::Read;
    let shown = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    // Opened without waiting (a FIFO would wait for a writer), then judged by what was opened
    // (no window for a FIFO to be put in its place between a look and the opening).
    let file = {
        use std::os::unix::fs::OpenOptionsExt;
        let nonblock = rustix::fs::OFlags::NONBLOCK.bits() as i32;
        std::fs::OpenOptions::new().read(true).custom_flags(nonblock).open(path).map_err(|e| shown(&e))?
    };
    let meta = file.metadata().map_err(|e| shown(&e))?;
    if !meta.is_file() {
        return Err(format!("{}: not a regular file: expected a .npy volume", path.display()));
    }
    let mut head = vec![];
    // The fixed part (12 bytes at most), then the header it announces.
    (&file).take(12).read_to_end(&mut head).map_err(|e| shown(&e))?;
    let announced = match head.get(6) {
        Some(1) if head.len() >= 10 => 10 + u16::from_le_bytes([head[8], head[9]]) as usize,
        Some(2 | 3) if head.len() >= 12 => {
            12usize.saturating_add(u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as usize)
        }
        _ => head.len(),
    };
    let want = announced.min(12 + MAX_HEADER_BYTES);
    (&file).take(want.saturating_sub(head.len()) as u64).read_to_end(&mut head).map_err(|e| shown(&e))?;
    let header = parse_header(&head).map_err(|m| shown(&m))?;
    let expected = (header.offset as u64).saturating_add(header.data_bytes);
    if meta.len() != expected {
        return Err(format!(
            "{}: {} bytes, where its header (shape {:?} of {}-byte floats) declares {expected}",
            path.display(),
            meta.len(),
            header.shape,
            header.item
        ));
    }
    Ok(Volume { header, file, path: path.to_path_buf() })
}

impl Volume {
    /// Read the data in pieces, calling `f(index, value)` for each value with its index in the
    /// array (C-order indices, whatever the file's order) and the value as `f32`: nothing but a
    /// 1 MiB buffer is held besides what `f` keeps.
    pub fn for_each(mut self, mut f: impl FnMut(&[usize], f32)) -> Result<(), String> {
        use std::io::Read;
        let h = &self.header;
        let n = h.shape.len();
        let mut index = vec![0usize; n];
        // The axes from the fastest stored to the slowest.
        let order: Vec<usize> = if h.fortran { (0..n).collect() } else { (0..n).rev().collect() };
        let mut buf = vec![0u8; (1 << 20) / 8 * 8];
        let mut left = h.data_bytes;
        while left > 0 {
            let take = left.min(buf.len() as u64) as usize;
            self.file.read_exact(&mut buf[..take]).map_err(|e| format!("{}: {e}", self.path.display()))?;
            left -= take as u64;
            for c in buf[..take].chunks_exact(h.item) {
                let v = if h.item == 4 {
                    f32::from_le_bytes([c[0], c[1], c[2], c[3]])
                } else {
                    f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]) as f32
                };
                f(&index, v);
                for &a in &order {
                    index[a] += 1;
                    if index[a] < h.shape[a] {
                        break;
                    }
                    index[a] = 0;
                }
            }
        }
        Ok(())
    }
}

/// Values stored in Fortran order (the first index fastest) rearranged into C order.
fn fortran_to_c(shape: &[usize], stored: &[f32]) -> Vec<f32> {
    let n = shape.len();
    // Fortran strides: the first index fastest.
    let mut strides = vec![1usize; n];
    for a in 1..n {
        strides[a] = strides[a - 1] * shape[a - 1];
    }
    let mut out = Vec::with_capacity(stored.len());
    let mut index = vec![0usize; n];
    for _ in 0..stored.len() {
        out.push(stored[index.iter().zip(&strides).map(|(i, s)| i * s).sum::<usize>()]);
        // The next C-order index: the last fastest.
        for a in (0..n).rev() {
            index[a] += 1;
            if index[a] < shape[a] {
                break;
            }
            index[a] = 0;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn round_trip_and_alignment() {
        let data = [1.0, -2.5, 3.25, f64::MAX, 0.0, 1e-300];
        for shape in [vec![6], vec![2, 3]] {
            let b = super::to_bytes(&shape, &data);
            let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
            assert_eq!((10 + hlen) % 64, 0);
            assert_eq!(super::from_bytes(&b), Some((shape, data.to_vec())));
        }
    }

    /// `.npy` bytes of `values` (`<f4`) with `shape`, as NumPy writes them.
    fn f4(shape: &str, fortran: bool, values: &[f32]) -> Vec<u8> {
        let header = format!(
            "{{'descr': '<f4', 'fortran_order': {}, 'shape': {shape}, }}\n",
            if fortran { "True" } else { "False" }
        );
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend((header.len() as u16).to_le_bytes());
        b.extend(header.as_bytes());
        b.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        b
    }

    /// a[i][j][k] = 100 i + 10 j + k of shape (2, 3, 2), in C and in Fortran order.
    fn both_orders() -> (Vec<f32>, Vec<f32>) {
        let c: Vec<f32> = (0..12).map(|n| (100 * (n / 6) + 10 * ((n / 2) % 3) + n % 2) as f32).collect();
        let mut fo = vec![0.0; 12];
        for i in 0..2 {
            for j in 0..3 {
                for k in 0..2 {
                    fo[i + 2 * j + 6 * k] = (100 * i + 10 * j + k) as f32;
                }
            }
        }
        (c, fo)
    }

    /// C and Fortran order give the same array; f8 reads as f32; a wrong dtype or size is an
    /// error in words.
    #[test]
    fn floats_in_either_order() {
        let (c, fo) = both_orders();
        let a = super::read_floats(&f4("(2, 3, 2)", false, &c)).unwrap();
        let b = super::read_floats(&f4("(2, 3, 2)", true, &fo)).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.shape, [2, 3, 2]);
        assert_eq!(a.values[(3 + 2) * 2 + 1], 121.0);
        let f8 = super::read_floats(&super::to_bytes(&[2, 2], &[1.5, -2.0, 3.0, 4.0])).unwrap();
        assert_eq!(f8.values, [1.5, -2.0, 3.0, 4.0]);
        let mut int = f4("(3,)", false, &[1.0, 2.0, 3.0]);
        int[22] = b'i'; // '<f4' → '<i4'
        assert!(super::read_floats(&int).unwrap_err().contains("expected little-endian float32"));
        assert!(super::read_floats(&f4("(4,)", false, &[1.0, 2.0, 3.0])).unwrap_err().contains("expected 16"));
        assert!(super::read_floats(b"not npy at all").is_err());
    }

    /// A volume file streams each value with its C-order index whatever the file's order, and
    /// its length must be what the header declares.
    #[test]
    fn volumes_stream_by_index() {
        let (c, fo) = both_orders();
        let tmp = tempfile::tempdir().unwrap();
        for (name, fortran, values) in [("c.npy", false, &c), ("f.npy", true, &fo)] {
            let path = tmp.path().join(name);
            std::fs::write(&path, f4("(2, 3, 2)", fortran, values)).unwrap();
            let mut seen = 0;
            super::open_volume(&path)
                .unwrap()
                .for_each(|ix, v| {
                    assert_eq!(v, (100 * ix[0] + 10 * ix[1] + ix[2]) as f32, "{name} {ix:?}");
                    seen += 1;
                })
                .unwrap();
            assert_eq!(seen, 12);
            let mut b = f4("(2, 3, 2)", fortran, values);
            b.pop();
            std::fs::write(&path, b).unwrap();
            assert!(super::open_volume(&path).err().unwrap().contains("where its header"));
        }
    }
}
