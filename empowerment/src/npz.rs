//! NumPy's `.npz` files: a zip archive of `.npy` arrays (format version 1.0, C order,
//! little-endian), stored uncompressed, as `numpy.savez` writes them. Written by the
//! dataset command, read back by the scoring command; `numpy.load` reads both ways.
//!
//! A `.npy` array is the magic `\x93NUMPY`, the version `1 0`, a little-endian u16
//! header length, then a Python dict literal (`descr`, `fortran_order`, `shape`) padded
//! with spaces to a multiple of 64 bytes and ending in a newline, then the data.

use std::io::{Cursor, Read, Write};

/// The data of one array (its dtype follows from the variant).
#[derive(Clone, Debug, PartialEq)]
pub enum Data {
    /// `|u1`.
    U8(Vec<u8>),
    /// `|b1`.
    Bool(Vec<bool>),
    /// `<u2`.
    U16(Vec<u16>),
    /// `<u4`.
    U32(Vec<u32>),
    /// `<i8`.
    I64(Vec<i64>),
    /// `<u8`.
    U64(Vec<u64>),
    /// `<f4`.
    F32(Vec<f32>),
    /// `<f8`.
    F64(Vec<f64>),
    /// `<U{n}`: fixed-width UTF-32 strings, n the longest.
    Str(Vec<String>),
}

impl Data {
    fn len(&self) -> usize {
        match self {
            Data::U8(v) => v.len(),
            Data::Bool(v) => v.len(),
            Data::U16(v) => v.len(),
            Data::U32(v) => v.len(),
            Data::I64(v) => v.len(),
            Data::U64(v) => v.len(),
            Data::F32(v) => v.len(),
            Data::F64(v) => v.len(),
            Data::Str(v) => v.len(),
        }
    }

    fn descr(&self) -> String {
        match self {
            Data::U8(_) => "|u1".into(),
            Data::Bool(_) => "|b1".into(),
            Data::U16(_) => "<u2".into(),
            Data::U32(_) => "<u4".into(),
            Data::I64(_) => "<i8".into(),
            Data::U64(_) => "<u8".into(),
            Data::F32(_) => "<f4".into(),
            Data::F64(_) => "<f8".into(),
            Data::Str(v) => format!(
                "<U{}",
                v.iter()
                    .map(|s| s.chars().count())
                    .max()
                    .unwrap_or(0)
                    .max(1)
            ),
        }
    }

    fn bytes(&self) -> Vec<u8> {
        match self {
            Data::U8(v) => v.clone(),
            Data::Bool(v) => v.iter().map(|&b| b as u8).collect(),
            Data::U16(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::U32(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::I64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::U64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::F32(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::F64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::Str(v) => {
                let n = v
                    .iter()
                    .map(|s| s.chars().count())
                    .max()
                    .unwrap_or(0)
                    .max(1);
                let mut out = Vec::with_capacity(v.len() * n * 4);
                for s in v {
                    let mut k = 0;
                    for c in s.chars() {
                        out.extend_from_slice(&(c as u32).to_le_bytes());
                        k += 1;
                    }
                    out.resize(out.len() + (n - k) * 4, 0);
                }
                out
            }
        }
    }
}

/// One named array.
#[derive(Clone, Debug, PartialEq)]
pub struct Array {
    /// Its name (the archive holds `{name}.npy`).
    pub name: String,
    /// Its shape; `[]` for a scalar.
    pub shape: Vec<usize>,
    /// Its elements, C order.
    pub data: Data,
}

impl Array {
    /// An array; the shape's product must equal the data's length.
    pub fn new(name: &str, shape: &[usize], data: Data) -> Array {
        debug_assert_eq!(shape.iter().product::<usize>(), data.len(), "{name}");
        Array {
            name: name.to_string(),
            shape: shape.to_vec(),
            data,
        }
    }
}

fn shape_literal(shape: &[usize]) -> String {
    match shape {
        [] => "()".into(),
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// One array as `.npy` bytes.
pub fn npy(a: &Array) -> Vec<u8> {
    let dict = format!(
        "{{'descr': '{}', 'fortran_order': False, 'shape': {}, }}",
        a.data.descr(),
        shape_literal(&a.shape)
    );
    // magic (6) + version (2) + length (2) + dict + padding + '\n' = a multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let header_len = dict.len() + 1 + (64 - unpadded % 64) % 64;
    let mut out = Vec::with_capacity(10 + header_len);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.resize(10 + header_len - 1, b' ');
    out.push(b'\n');
    out.extend_from_slice(&a.data.bytes());
    out
}

/// The arrays as the bytes of an `.npz` file (stored entries, fixed timestamps: the same
/// arrays give the same bytes).
pub fn to_npz(arrays: &[Array]) -> std::io::Result<Vec<u8>> {
    let mut z = zip::ZipWriter::new(Cursor::new(Vec::new()));
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Stored)
        .large_file(true);
    for a in arrays {
        z.start_file(format!("{}.npy", a.name), opts)
            .map_err(std::io::Error::other)?;
        z.write_all(&npy(a))?;
    }
    Ok(z.finish().map_err(std::io::Error::other)?.into_inner())
}

/// An array read back: its dtype's `descr`, shape and raw little-endian bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Raw {
    /// `<f8`, `|u1`, ...
    pub descr: String,
    /// Its shape.
    pub shape: Vec<usize>,
    /// The data bytes.
    pub bytes: Vec<u8>,
}

impl Raw {
    /// The elements as f64, from any integer, bool or float dtype.
    pub fn to_f64(&self) -> Result<Vec<f64>, String> {
        let b = &self.bytes;
        let of = |n: usize| b.chunks_exact(n);
        Ok(match self.descr.as_str() {
            "<f8" => of(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8")))
                .collect(),
            "<f4" => of(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4")) as f64)
                .collect(),
            "<i8" => of(8)
                .map(|c| i64::from_le_bytes(c.try_into().expect("8")) as f64)
                .collect(),
            "<u8" => of(8)
                .map(|c| u64::from_le_bytes(c.try_into().expect("8")) as f64)
                .collect(),
            "<i4" => of(4)
                .map(|c| i32::from_le_bytes(c.try_into().expect("4")) as f64)
                .collect(),
            "<u4" => of(4)
                .map(|c| u32::from_le_bytes(c.try_into().expect("4")) as f64)
                .collect(),
            "<u2" => of(2)
                .map(|c| u16::from_le_bytes(c.try_into().expect("2")) as f64)
                .collect(),
            "|u1" | "|b1" => b.iter().map(|&x| x as f64).collect(),
            d => return Err(format!("dtype {d} is not a number this reader knows")),
        })
    }
}

/// Parse one `.npy` file (version 1, 2 or 3; C order).
pub fn parse_npy(b: &[u8]) -> Result<Raw, String> {
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        return Err("not a .npy array (no \\x93NUMPY magic)".into());
    }
    let (len, start) = match b[6] {
        1 => (u16::from_le_bytes([b[8], b[9]]) as usize, 10),
        2 | 3 if b.len() >= 12 => (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12),
        v => return Err(format!(".npy version {v} is not one this reader knows")),
    };
    let header = b
        .get(start..start + len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or("a .npy header runs past the end of the array")?;
    let field = |key: &str| -> Result<&str, String> {
        let at = header
            .find(&format!("'{key}':"))
            .ok_or(format!("the .npy header has no '{key}'"))?;
        Ok(header[at + key.len() + 3..].trim_start())
    };
    let descr = field("descr")?;
    let descr = descr
        .strip_prefix('\'')
        .and_then(|d| d.split('\'').next())
        .ok_or("the .npy header's descr is not a string")?
        .to_string();
    if field("fortran_order")?.starts_with("True") {
        return Err("Fortran-ordered arrays are not read; save it in C order".into());
    }
    let shape = field("shape")?;
    let shape = &shape[1..shape
        .find(')')
        .ok_or("the .npy header's shape is not closed")?];
    let shape: Vec<usize> = shape
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse()
                .map_err(|_| format!("shape entry '{s}' is not a size"))
        })
        .collect::<Result<_, _>>()?;
    let item = match descr
        .get(1..)
        .and_then(|d| d.get(1..))
        .map(str::parse::<usize>)
    {
        Some(Ok(n)) if descr.as_bytes()[1] == b'U' => 4 * n,
        Some(Ok(n)) => n,
        _ => return Err(format!("dtype {descr} is not one this reader knows")),
    };
    if descr.starts_with('>') {
        return Err(format!("big-endian dtype {descr} is not read"));
    }
    let need = shape.iter().product::<usize>() * item;
    let data = &b[start + len..];
    if data.len() < need {
        return Err(format!(
            "the array holds {} bytes, its shape needs {need}",
            data.len()
        ));
    }
    Ok(Raw {
        descr,
        shape,
        bytes: data[..need].to_vec(),
    })
}

/// Every array of an `.npz` file's bytes, by name (without `.npy`).
pub fn read_npz(bytes: &[u8]) -> Result<Vec<(String, Raw)>, String> {
    let mut z = zip::ZipArchive::new(Cursor::new(bytes))
        .map_err(|e| format!("not an .npz archive ({e})"))?;
    let mut out = Vec::new();
    for i in 0..z.len() {
        let mut f = z
            .by_index(i)
            .map_err(|e| format!("cannot read entry {i}: {e}"))?;
        let name = f
            .name()
            .map_err(|e| format!("entry {i} has no readable name: {e}"))?
            .trim_end_matches(".npy")
            .to_string();
        let mut b = Vec::new();
        f.read_to_end(&mut b)
            .map_err(|e| format!("cannot read {name}: {e}"))?;
        out.push((
            name.clone(),
            parse_npy(&b).map_err(|e| format!("{name}: {e}"))?,
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes numpy 1.26 writes for `np.save(f, np.array([1.5, -2.0]))`, the header
    /// typed from its documented layout (a dict padded to 64 bytes in all).
    #[test]
    fn npy_header_is_numpys() {
        let b = npy(&Array::new("x", &[2], Data::F64(vec![1.5, -2.0])));
        let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }";
        assert_eq!(&b[..8], b"\x93NUMPY\x01\x00");
        assert_eq!(u16::from_le_bytes([b[8], b[9]]), 118);
        assert_eq!(&b[10..10 + header.len()], header.as_bytes());
        assert_eq!(b[127], b'\n');
        assert_eq!(b.len(), 128 + 16);
        assert_eq!(&b[128..136], &1.5f64.to_le_bytes());
    }

    #[test]
    fn arrays_read_back() {
        let arrays = vec![
            Array::new("e", &[2, 2], Data::F64(vec![0.0, 1.0, 2.5, 3.0])),
            Array::new("h", &[3], Data::U32(vec![1, 3, 8])),
            Array::new("ok", &[2], Data::Bool(vec![true, false])),
            Array::new("tool", &[], Data::Str(vec!["axe".into()])),
        ];
        let back = read_npz(&to_npz(&arrays).unwrap()).unwrap();
        assert_eq!(back.len(), 4);
        assert_eq!(back[0].0, "e");
        assert_eq!(back[0].1.shape, vec![2, 2]);
        assert_eq!(back[0].1.to_f64().unwrap(), vec![0.0, 1.0, 2.5, 3.0]);
        assert_eq!(back[1].1.to_f64().unwrap(), vec![1.0, 3.0, 8.0]);
        assert_eq!(back[2].1.descr, "|b1");
        assert_eq!(back[3].1.descr, "<U3");
        assert_eq!(back[3].1.shape, Vec::<usize>::new());
        assert_eq!(back[3].1.bytes, b"a\0\0\0x\0\0\0e\0\0\0".to_vec());
    }
}
