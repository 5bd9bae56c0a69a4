//! CDR as ROS 2 serialises it: little-endian (encapsulation `00 01 00 00`),
//! each primitive aligned to its size relative to the end of that 4-byte
//! header, strings as a `u32` length that counts the terminating NUL,
//! sequences as a `u32` count followed by the elements, fixed arrays as
//! their elements alone.

/// The encapsulation header of little-endian plain CDR.
pub const HEADER: [u8; 4] = [0, 1, 0, 0];

/// Writes one CDR message.
#[derive(Debug)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl CdrWriter {
    /// A message whose body will be about `capacity` bytes.
    pub fn with_capacity(capacity: usize) -> Self {
        let mut buf = Vec::with_capacity(capacity + HEADER.len());
        buf.extend_from_slice(&HEADER);
        Self { buf }
    }

    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - HEADER.len();
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// A `uint8` or `bool`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint64`.
    pub fn u64(&mut self, v: u64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A sequence's or string's length.
    fn len(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    /// A `string`.
    pub fn string(&mut self, s: &str) {
        self.len(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// A `uint8[]`.
    pub fn bytes(&mut self, b: &[u8]) {
        self.len(b.len());
        self.buf.extend_from_slice(b);
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self, v: &[f64]) {
        self.len(v.len());
        self.f64_array(v);
    }

    /// A `float64[N]` (no length).
    pub fn f64_array(&mut self, v: &[f64]) {
        for &x in v {
            self.f64(x);
        }
    }

    /// A `bool[]`.
    pub fn bool_seq(&mut self, v: &[bool]) {
        self.len(v.len());
        for &b in v {
            self.u8(u8::from(b));
        }
    }

    /// A `string[]`.
    pub fn string_seq(&mut self, v: &[String]) {
        self.len(v.len());
        for s in v {
            self.string(s);
        }
    }

    /// The message's bytes.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Why a CDR message could not be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The message ended inside a field.
    #[error("the message ends at byte {at} inside the field {field}")]
    Short {
        /// The field.
        field: &'static str,
        /// Where the message ended.
        at: usize,
    },
    /// Not little-endian plain CDR.
    #[error("the encapsulation header is {0:02x?}, expected 00 01 00 00 (little-endian CDR)")]
    Header([u8; 4]),
    /// A string that is not UTF-8 or not NUL-terminated.
    #[error("the string {field} is not NUL-terminated UTF-8")]
    BadString {
        /// The field.
        field: &'static str,
    },
}

/// Reads one CDR message.
#[derive(Debug)]
pub struct CdrReader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// A reader of `buf`, which starts with the encapsulation header.
    pub fn new(buf: &'a [u8]) -> Result<Self, CdrError> {
        let head: [u8; 4] =
            buf.get(..4)
                .and_then(|h| h.try_into().ok())
                .ok_or(CdrError::Short {
                    field: "encapsulation header",
                    at: buf.len(),
                })?;
        if head != HEADER {
            return Err(CdrError::Header(head));
        }
        Ok(Self { buf, pos: 4 })
    }

    fn align(&mut self, n: usize) {
        let pos = self.pos - HEADER.len();
        self.pos += (n - pos % n) % n;
    }

    fn take(&mut self, n: usize, field: &'static str) -> Result<&'a [u8], CdrError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.buf.len());
        let Some(end) = end else {
            return Err(CdrError::Short {
                field,
                at: self.buf.len(),
            });
        };
        let out = &self.buf[self.pos..end];
        self.pos = end;
        Ok(out)
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        let b = self.take(N, field)?;
        b.try_into().map_err(|_| CdrError::Short {
            field,
            at: self.buf.len(),
        })
    }

    /// A `uint8`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.array::<1>(field)?[0])
    }

    /// A `bool`.
    pub fn bool(&mut self, field: &'static str) -> Result<bool, CdrError> {
        Ok(self.u8(field)? != 0)
    }

    /// A `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        self.align(4);
        Ok(u32::from_le_bytes(self.array(field)?))
    }

    /// An `int32`.
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CdrError> {
        self.align(4);
        Ok(i32::from_le_bytes(self.array(field)?))
    }

    /// A `uint64`.
    pub fn u64(&mut self, field: &'static str) -> Result<u64, CdrError> {
        self.align(8);
        Ok(u64::from_le_bytes(self.array(field)?))
    }

    /// A `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        self.align(8);
        Ok(f64::from_le_bytes(self.array(field)?))
    }

    fn len(&mut self, field: &'static str) -> Result<usize, CdrError> {
        let n = self.u32(field)?;
        let n = usize::try_from(n).unwrap_or(usize::MAX);
        // Every element takes at least a byte: a longer count is a lie.
        if n > self.buf.len() - self.pos {
            return Err(CdrError::Short {
                field,
                at: self.buf.len(),
            });
        }
        Ok(n)
    }

    /// A `string`.
    pub fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let n = self.len(field)?;
        let b = self.take(n, field)?;
        match b.split_last() {
            Some((0, s)) => std::str::from_utf8(s)
                .map(str::to_owned)
                .map_err(|_| CdrError::BadString { field }),
            _ => Err(CdrError::BadString { field }),
        }
    }

    /// A `uint8[]`, borrowed.
    pub fn bytes(&mut self, field: &'static str) -> Result<&'a [u8], CdrError> {
        let n = self.len(field)?;
        self.take(n, field)
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self, field: &'static str) -> Result<Vec<f64>, CdrError> {
        let n = self.len(field)?;
        (0..n).map(|_| self.f64(field)).collect()
    }

    /// A `float64[N]`.
    pub fn f64_array<const N: usize>(&mut self, field: &'static str) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(field)?;
        }
        Ok(out)
    }

    /// A `bool[]`.
    pub fn bool_seq(&mut self, field: &'static str) -> Result<Vec<bool>, CdrError> {
        let n = self.len(field)?;
        (0..n).map(|_| self.bool(field)).collect()
    }

    /// A `string[]`.
    pub fn string_seq(&mut self, field: &'static str) -> Result<Vec<String>, CdrError> {
        let n = self.len(field)?;
        (0..n).map(|_| self.string(field)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_aligned_after_the_header_and_strings_count_their_nul() {
        let mut w = CdrWriter::with_capacity(32);
        w.u8(7);
        w.u32(0x0102_0304);
        w.string("ab");
        w.f64(1.5);
        let b = w.finish();
        assert_eq!(&b[..4], &HEADER);
        assert_eq!(b[4], 7);
        assert_eq!(&b[5..8], &[0, 0, 0], "padding to 4");
        assert_eq!(&b[8..12], &[4, 3, 2, 1]);
        assert_eq!(&b[12..16], &[3, 0, 0, 0], "length counts the NUL");
        assert_eq!(&b[16..19], b"ab\0");
        assert_eq!(b[19], 0, "padding to 8 after the string");
        assert_eq!(
            &b[20..28],
            &1.5f64.to_le_bytes(),
            "the double is aligned to 8"
        );
        assert_eq!(b.len(), 4 + 24);
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u8("a").unwrap(), 7);
        assert_eq!(r.u32("b").unwrap(), 0x0102_0304);
        assert_eq!(r.string("c").unwrap(), "ab");
        assert_eq!(r.f64("d").unwrap().to_bits(), 1.5f64.to_bits());
        assert!(r.u8("e").is_err());
    }

    #[test]
    fn a_sequence_longer_than_the_message_is_an_error_not_an_allocation() {
        let mut w = CdrWriter::with_capacity(8);
        w.u32(u32::MAX);
        let b = w.finish();
        let mut r = CdrReader::new(&b).unwrap();
        assert!(matches!(r.bytes("data"), Err(CdrError::Short { .. })));
        assert!(CdrReader::new(&[0, 0, 0, 0]).is_err(), "big-endian refused");
    }
}
