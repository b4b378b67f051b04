//! Little-endian byte encoding with bounds checks and a checksum, for guide serialization.

use alloc::vec::Vec;

use crate::error::{DecodeError, Error};
use crate::update_rule::{IntegralEstimator, LearningRate, UpdateRule};

/// The first bytes of every serialized guide.
pub(crate) const MAGIC: &[u8; 8] = b"LODESTAR";

/// [`DecodeError::InvalidField`] as an [`Error`].
pub(crate) fn invalid_field(field: &'static str, index: usize, requirement: &'static str) -> Error {
    Error::Decode(DecodeError::InvalidField { field, index, requirement })
}

/// Checks the magic, checksum, structure tag and format version of a serialized guide and
/// returns a reader positioned after them.
pub(crate) fn open_guide_bytes(bytes: &[u8], version: u32, tag: u32) -> Result<ByteReader<'_>, Error> {
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err(DecodeError::BadMagic.into());
    }
    let mut r = ByteReader::verified(bytes)?;
    r.take(MAGIC.len())?;
    let found = r.u32()?;
    let structure = r.u32()?;
    // The structure first: another structure's bytes are that, whatever their version.
    if structure != tag {
        return Err(DecodeError::WrongStructure { found: structure, expected: tag }.into());
    }
    if found != version {
        return Err(DecodeError::UnsupportedVersion { found, supported: version }.into());
    }
    Ok(r)
}

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

    /// Two u32 words, low first.
    pub(crate) fn put_u64(&mut self, value: u64) {
        self.put_u32(value as u32);
        self.put_u32((value >> 32) as u32);
    }

    /// The magic, the format version and the structure tag.
    /// A grid's memory budget and its optional explicit resolution (a 0/1 flag, then
    /// three cell counts), as [`ByteReader::budget_and_resolution`] reads them.
    #[cfg_attr(not(any(feature = "mixture", feature = "env", feature = "lights")), allow(dead_code))]
    pub(crate) fn put_budget_and_resolution(&mut self, budget_bytes: usize, resolution: Option<[u32; 3]>) {
        self.put_u64(budget_bytes as u64);
        self.put_u32(resolution.is_some() as u32);
        resolution.unwrap_or([0; 3]).iter().for_each(|&n| self.put_u32(n));
    }

    pub(crate) fn put_header(&mut self, version: u32, tag: u32) {
        self.put_bytes(MAGIC);
        self.put_u32(version);
        self.put_u32(tag);
    }

    /// u32 learning-rate kind · f32 its parameter · u32 integral estimator.
    pub(crate) fn put_update_rule(&mut self, rule: &UpdateRule) {
        let (kind, parameter) = match rule.learning_rate {
            LearningRate::Exponential { alpha } => (0, alpha),
            LearningRate::SimpleAverage => (1, 0.0),
            LearningRate::RegionVisits => (2, 0.0),
            LearningRate::Global { exponent } => (3, exponent),
        };
        self.put_u32(kind);
        self.put_f32(parameter);
        self.put_u32(match rule.integral {
            IntegralEstimator::BsdfWeightedSum => 0,
            IntegralEstimator::StratifiedPatches => 1,
            IntegralEstimator::MaxEntry => 2,
            IntegralEstimator::BsdfSampled => 3,
            IntegralEstimator::PathContinuation => 4,
        });
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

    /// Two u32 words, low first.
    pub(crate) fn u64(&mut self) -> Result<u64, DecodeError> {
        let low = self.u32()? as u64;
        Ok(low | (self.u32()? as u64) << 32)
    }

    pub(crate) fn vec3(&mut self) -> Result<glam::Vec3, DecodeError> {
        Ok(glam::Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }

    /// What [`ByteWriter::put_update_rule`] wrote (ranges are checked by the caller's
    /// settings validation).
    pub(crate) fn update_rule(&mut self) -> Result<UpdateRule, Error> {
        let kind = self.u32()?;
        let parameter = self.f32()?;
        let learning_rate = match kind {
            0 => LearningRate::Exponential { alpha: parameter },
            1 => LearningRate::SimpleAverage,
            2 => LearningRate::RegionVisits,
            3 => LearningRate::Global { exponent: parameter },
            _ => return Err(invalid_field("learning_rate", 0, "a kind in 0..=3")),
        };
        let integral = match self.u32()? {
            0 => IntegralEstimator::BsdfWeightedSum,
            1 => IntegralEstimator::StratifiedPatches,
            2 => IntegralEstimator::MaxEntry,
            3 => IntegralEstimator::BsdfSampled,
            4 => IntegralEstimator::PathContinuation,
            _ => return Err(invalid_field("integral", 0, "a kind in 0..=4")),
        };
        Ok(UpdateRule { learning_rate, integral })
    }

    /// What [`ByteWriter::put_budget_and_resolution`] wrote.
    #[cfg_attr(not(any(feature = "mixture", feature = "env", feature = "lights")), allow(dead_code))]
    pub(crate) fn budget_and_resolution(&mut self) -> Result<(usize, Option<[u32; 3]>), Error> {
        let budget_bytes = usize::try_from(self.u64()?).map_err(|_| invalid_field("budget_bytes", 0, "addressable"))?;
        let given = self.flag("resolution_given")?;
        let resolution = [self.u32()?, self.u32()?, self.u32()?];
        Ok((budget_bytes, given.then_some(resolution)))
    }

    /// A 0/1 word as a flag; anything else is an invalid `field`.
    #[cfg_attr(
        not(any(feature = "mixture", feature = "env", feature = "lights", feature = "tree", feature = "volume")),
        allow(dead_code)
    )]
    pub(crate) fn flag(&mut self, field: &'static str) -> Result<bool, Error> {
        match self.u32()? {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(invalid_field(field, 0, "0 or 1")),
        }
    }

    /// Fails unless exactly `needed` bytes are left: checked before the tables they hold
    /// are allocated, so a damaged count cannot demand memory.
    pub(crate) fn expect_remaining(&self, needed: usize) -> Result<(), DecodeError> {
        match self.remaining() {
            left if left < needed => Err(DecodeError::Truncated { offset: self.offset, needed, available: left }),
            left if left > needed => Err(DecodeError::TrailingBytes { count: left - needed }),
            _ => Ok(()),
        }
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
