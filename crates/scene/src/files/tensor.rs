//! The RGL "tensor file" container (Dupuy & Jakob's measured BRDF database, `.bsdf`):
//! named n-dimensional arrays. Reading checks every size and offset against the file before
//! anything is allocated; writing is for tests and scene generators.
//!
//! Layout (little-endian): the 12 bytes `tensor_file\0`, version 1.0 (two bytes), the number
//! of fields (u32), then per field its name length (u16), name, number of dimensions (u16),
//! type (u8), byte offset of its data (u64) and its shape (u64 per dimension).

use std::collections::BTreeMap;

const MAGIC: &[u8; 12] = b"tensor_file\0";

/// Element types; the numbers are the file's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    U8 = 1,
    I8 = 2,
    U16 = 3,
    I16 = 4,
    U32 = 5,
    I32 = 6,
    U64 = 7,
    I64 = 8,
    F16 = 9,
    F32 = 10,
    F64 = 11,
}

impl Dtype {
    fn from_byte(b: u8) -> Option<Dtype> {
        use Dtype::*;
        [U8, I8, U16, I16, U32, I32, U64, I64, F16, F32, F64]
            .into_iter()
            .find(|d| *d as u8 == b)
    }

    fn size(self) -> usize {
        use Dtype::*;
        match self {
            U8 | I8 => 1,
            U16 | I16 | F16 => 2,
            U32 | I32 | F32 => 4,
            U64 | I64 | F64 => 8,
        }
    }
}

/// One named array: its type, shape (outermost first) and raw little-endian bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub dtype: Dtype,
    pub shape: Vec<usize>,
    pub bytes: Vec<u8>,
}

impl Field {
    /// The values of a float32 field whose shape has `ndim` dimensions.
    pub fn f32s(&self, name: &str, ndim: usize) -> Result<Vec<f32>, String> {
        if self.dtype != Dtype::F32 || self.shape.len() != ndim {
            return Err(format!(
                "field '{name}' is {:?} with {} dimension(s); expected float32 with {ndim}",
                self.dtype,
                self.shape.len()
            ));
        }
        Ok(self
            .bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect())
    }
}

/// Parses a tensor file. Errors say what is wrong and where in the file.
pub fn parse_tensor(bytes: &[u8]) -> Result<BTreeMap<String, Field>, String> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(12)? != MAGIC {
        return Err("not a tensor file (it does not start with \"tensor_file\")".into());
    }
    let version = r.take(2)?;
    if version != [1, 0] {
        return Err(format!(
            "tensor file version {}.{} is not supported (Kiln reads 1.0)",
            version[0], version[1]
        ));
    }
    let n_fields = r.u32()?;
    let mut fields = BTreeMap::new();
    for _ in 0..n_fields {
        let name_len = r.u16()? as usize;
        let name = String::from_utf8(r.take(name_len)?.to_vec())
            .map_err(|_| format!("a field name at byte {} is not UTF-8", r.at - name_len))?;
        let ndim = r.u16()? as usize;
        let dtype_byte = r.take(1)?[0];
        let dtype = Dtype::from_byte(dtype_byte)
            .ok_or_else(|| format!("field '{name}' has unknown type {dtype_byte}"))?;
        let offset = r.u64()?;
        let mut shape = Vec::with_capacity(ndim.min(16));
        let mut total = dtype.size() as u64;
        for _ in 0..ndim {
            let n = r.u64()?;
            total = total
                .checked_mul(n)
                .ok_or_else(|| format!("field '{name}': its shape overflows"))?;
            shape.push(n as usize);
        }
        let end = offset
            .checked_add(total)
            .filter(|&e| e <= bytes.len() as u64)
            .ok_or_else(|| {
                format!(
                    "field '{name}' needs bytes {offset}..{} but the file has {} (truncated?)",
                    offset.saturating_add(total),
                    bytes.len()
                )
            })?;
        let data = bytes[offset as usize..end as usize].to_vec();
        if fields
            .insert(
                name.clone(),
                Field {
                    dtype,
                    shape,
                    bytes: data,
                },
            )
            .is_some()
        {
            return Err(format!("field '{name}' appears twice"));
        }
    }
    Ok(fields)
}

/// Encodes fields as a tensor file.
pub fn write_tensor(fields: &[(&str, Field)]) -> Vec<u8> {
    let header_len: usize = 12
        + 2
        + 4
        + fields
            .iter()
            .map(|(n, f)| 2 + n.len() + 2 + 1 + 8 + 8 * f.shape.len())
            .sum::<usize>();
    let mut out = Vec::with_capacity(header_len);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(fields.len() as u32).to_le_bytes());
    let mut offset = header_len as u64;
    for (name, f) in fields {
        out.extend_from_slice(&(name.len() as u16).to_le_bytes());
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(&(f.shape.len() as u16).to_le_bytes());
        out.push(f.dtype as u8);
        out.extend_from_slice(&offset.to_le_bytes());
        for &n in &f.shape {
            out.extend_from_slice(&(n as u64).to_le_bytes());
        }
        offset += f.bytes.len() as u64;
    }
    for (_, f) in fields {
        out.extend_from_slice(&f.bytes);
    }
    out
}

/// A float32 field of the given shape (for [`write_tensor`]).
pub fn f32_field(shape: &[usize], values: &[f32]) -> Field {
    assert_eq!(shape.iter().product::<usize>(), values.len());
    Field {
        dtype: Dtype::F32,
        shape: shape.to_vec(),
        bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(format!(
                "the header ends early (at byte {} of {}): truncated?",
                self.at,
                self.bytes.len()
            ));
        };
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take(2)?.try_into().unwrap()))
    }

    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }

    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_rejects_damage() {
        let a = f32_field(&[2, 3], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        let b = Field {
            dtype: Dtype::U8,
            shape: vec![1],
            bytes: vec![7],
        };
        let bytes = write_tensor(&[("a", a.clone()), ("jacobian", b.clone())]);
        let fields = parse_tensor(&bytes).unwrap();
        assert_eq!(fields["a"], a);
        assert_eq!(fields["jacobian"], b);
        assert_eq!(fields["a"].f32s("a", 2).unwrap()[5], 6.0);
        assert!(fields["a"].f32s("a", 3).is_err());
        // Every truncation is an error, never a panic.
        for n in 0..bytes.len() {
            assert!(parse_tensor(&bytes[..n]).is_err(), "truncated to {n}");
        }
        let mut bad = bytes.clone();
        bad[0] = b'x';
        assert!(
            parse_tensor(&bad)
                .unwrap_err()
                .contains("not a tensor file")
        );
        // A shape claiming more than the file holds.
        let mut huge = bytes.clone();
        let shape_at = 12 + 2 + 4 + 2 + 1 + 2 + 1 + 8;
        huge[shape_at..shape_at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(parse_tensor(&huge).is_err());
    }
}
