//! NumPy `.npy` (format 1.0) for little-endian `f64` arrays in C order.

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
}
