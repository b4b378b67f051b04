//! Little-endian byte encoding with bounds checks and a checksum, for guide serialization.

use alloc::vec::Vec;

use crate::error::DecodeError;

/// FNV-1a, 64 bit. Every step is a bijection of the state, so changing any single byte
/// always changes the checksum; that is the damage this format must detect.
pub(crate) fn fnv1a_64(bytes: &[u8]) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for &b in bytes {
        hash ^= b as u64;
        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
    hash
}

/// Recomputes the trailing 8-byte checksum of a serialized guide after its other bytes
/// were edited on purpose, so tests and fuzzers can reach the field checks behind the
/// checksum. Buffers shorter than 8 bytes are left alone.
pub fn reseal_checksum(bytes: &mut [u8]) {
    if let Some(body) = bytes.len().checked_sub(8) {
        let checksum = fnv1a_64(&bytes[..body]);
        bytes[body..].copy_from_slice(&checksum.to_le_bytes());
    }
}

/// Appends fields to a byte vector.
pub(crate) struct ByteWriter {
    bytes: Vec<u8>,
}

impl ByteWriter {
    pub(crate) fn with_capacity(capacity: usize) -> Self {
        Self { bytes: Vec::with_capacity(capacity) }
    }

    pub(crate) fn put_bytes(&mut self, bytes: &[u8]) {
        self.bytes.extend_from_slice(bytes);
    }

    pub(crate) fn put_u32(&mut self, value: u32) {
        self.put_bytes(&value.to_le_bytes());
    }

    pub(crate) fn put_f32(&mut self, value: f32) {
        self.put_bytes(&value.to_le_bytes());
    }

    /// Appends the checksum of everything written so far and returns the buffer.
    pub(crate) fn finish_with_checksum(mut self) -> Vec<u8> {
        let checksum = fnv1a_64(&self.bytes);
        self.put_bytes(&checksum.to_le_bytes());
        self.bytes
    }
}

/// Reads fields from a byte slice; every read checks the remaining length.
pub(crate) struct ByteReader<'a> {
    bytes: &'a [u8],
    offset: usize,
}

impl<'a> ByteReader<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, offset: 0 }
    }

    /// Splits off and verifies the trailing 8-byte checksum; the returned reader covers
    /// the checked contents only.
    pub(crate) fn verified(bytes: &'a [u8]) -> Result<Self, DecodeError> {
        let Some(body_len) = bytes.len().checked_sub(8) else {
            return Err(DecodeError::Truncated { offset: 0, needed: 8, available: bytes.len() });
        };
        let (body, tail) = bytes.split_at(body_len);
        let mut stored = [0u8; 8];
        stored.copy_from_slice(tail);
        let stored = u64::from_le_bytes(stored);
        let computed = fnv1a_64(body);
        if stored != computed {
            return Err(DecodeError::ChecksumMismatch { stored, computed });
        }
        Ok(Self::new(body))
    }

    pub(crate) fn offset(&self) -> usize {
        self.offset
    }

    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len() - self.offset
    }

    pub(crate) fn take(&mut self, count: usize) -> Result<&'a [u8], DecodeError> {
        if count > self.remaining() {
            return Err(DecodeError::Truncated { offset: self.offset, needed: count, available: self.remaining() });
        }
        let slice = &self.bytes[self.offset..self.offset + count];
        self.offset += count;
        Ok(slice)
    }

    pub(crate) fn u32(&mut self) -> Result<u32, DecodeError> {
        let mut raw = [0u8; 4];
        raw.copy_from_slice(self.take(4)?);
        Ok(u32::from_le_bytes(raw))
    }

    pub(crate) fn f32(&mut self) -> Result<f32, DecodeError> {
        Ok(f32::from_bits(self.u32()?))
    }

    /// Fails unless every byte was read.
    pub(crate) fn finish(self) -> Result<(), DecodeError> {
        match self.remaining() {
            0 => Ok(()),
            count => Err(DecodeError::TrailingBytes { count }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_checksum() {
        let mut w = ByteWriter::with_capacity(16);
        w.put_u32(7);
        w.put_f32(-2.5);
        let bytes = w.finish_with_checksum();
        let mut r = ByteReader::verified(&bytes).unwrap();
        assert_eq!(r.u32().unwrap(), 7);
        assert_eq!(r.f32().unwrap(), -2.5);
        assert!(matches!(r.u32(), Err(DecodeError::Truncated { offset: 8, needed: 4, available: 0 })));
        let mut damaged = bytes.clone();
        damaged[2] ^= 0x10;
        assert!(matches!(ByteReader::verified(&damaged), Err(DecodeError::ChecksumMismatch { .. })));
        assert!(matches!(
            ByteReader::verified(&bytes[..5]),
            Err(DecodeError::Truncated { .. }) | Err(DecodeError::ChecksumMismatch { .. })
        ));
    }

    #[test]
    fn every_single_byte_change_changes_the_checksum() {
        let data: Vec<u8> = (0..64u8).collect();
        let reference = fnv1a_64(&data);
        for i in 0..data.len() {
            for bit in 0..8 {
                let mut changed = data.clone();
                changed[i] ^= 1 << bit;
                assert_ne!(fnv1a_64(&changed), reference);
            }
        }
    }
}
