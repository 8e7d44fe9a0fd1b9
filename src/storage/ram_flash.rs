//! A NOR flash in RAM, strict enough to test the parameter store against power loss.
//!
//! [`RamFlash<PAGES, PAGE_BYTES, WORD>`] holds `PAGES` erase pages of `PAGE_BYTES` bytes each,
//! programmed in words of `WORD` bytes, and implements the async `embedded-storage` NOR traits
//! that `sequential-storage` uses. It enforces what real NOR flash enforces:
//!
//! - **alignment:** reads and writes start on a word boundary and cover whole words; erases
//!   start and end on page boundaries; anything outside the flash is `OutOfBounds`;
//! - **1 → 0 only:** a write may only clear bits; asking for a 0 → 1 change is an error (not a
//!   silent AND), so a logic error in the caller shows up;
//! - **write count:** [`WriteRule::Once`] allows one write per word between erases;
//!   [`WriteRule::TwiceWithZero`] (the STM32 rule the `MultiwriteNorFlash` marker relies on)
//!   allows a second write only if it writes all zeros;
//! - **erase granularity:** whole pages only; [`RamFlash::erase_counts`] tells how often each
//!   page was erased (wear).
//!
//! **Power cut.** [`RamFlash::cut_power_after`]`(n)` lets `n` more bytes be written or erased
//! (each programmed byte and each erased byte counts one). The next byte is left *half done*
//! and the flash goes dark: every later read, write and erase fails with
//! [`RamFlashError::PowerCut`] until [`RamFlash::restore_power`] (the "reboot"). Half done is the
//! harsher of the realistic models: a torn write programs only the zero bits of the byte's low
//! nibble (so the torn word holds neither the old nor the new value, and its write count is
//! used up, unless no bit of it changed: without ECC an operation that programmed nothing
//! leaves no trace); a torn erase sets only the low nibble to ones, the bytes before it are erased and
//! the bytes after it keep their old contents (a partially erased page). This is within the
//! `embedded-storage` contract ("contents of the written words are undefined", "contents of the
//! page are undefined") and exercises more states than a clean cut between bytes would.
//!
//! The whole flash is one plain value (no heap): cloning it or moving it from one simulated boot
//! to the next keeps its contents, write counts and wear statistics.

use core::fmt;

use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// How many times a word may be written between two erases of its page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum WriteRule {
    /// Exactly once.
    Once,
    /// Once, plus a second write of all zeros (STM32 internal flash; `MultiwriteNorFlash`).
    TwiceWithZero,
}

/// Why a [`RamFlash`] operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum RamFlashError {
    /// Offset or length is not a multiple of the word (read/write) or page (erase) size.
    NotAligned,
    /// The range reaches past the end of the flash, or `from > to`.
    OutOfBounds,
    /// The word at this offset may not be written again before an erase.
    WrittenTwice(u32),
    /// The write at this offset asks for a 0 → 1 bit change, which only an erase can do.
    ZeroToOne(u32),
    /// The power was cut; nothing works until [`RamFlash::restore_power`].
    PowerCut,
}

impl fmt::Display for RamFlashError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RamFlashError::NotAligned => f.write_str("flash access not aligned"),
            RamFlashError::OutOfBounds => f.write_str("flash access out of bounds"),
            RamFlashError::WrittenTwice(a) => write!(f, "word at {a:#x} already written"),
            RamFlashError::ZeroToOne(a) => write!(f, "write at {a:#x} needs a 0->1 change"),
            RamFlashError::PowerCut => f.write_str("power cut"),
        }
    }
}

impl core::error::Error for RamFlashError {}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            RamFlashError::NotAligned => NorFlashErrorKind::NotAligned,
            RamFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            _ => NorFlashErrorKind::Other,
        }
    }
}

/// Write count of a word, kept at the index of its first byte.
const ERASED: u8 = 0;
const WRITTEN_ONCE: u8 = 1;
const WRITTEN_TWICE: u8 = 2;

/// A NOR flash of `PAGES` × `PAGE_BYTES` bytes in RAM with `WORD`-byte program words.
///
/// Size in memory: about `2 × PAGES × PAGE_BYTES` bytes (contents + write counts); box it or
/// keep it in a `static` when that is large.
#[derive(Clone)]
pub struct RamFlash<const PAGES: usize, const PAGE_BYTES: usize, const WORD: usize> {
    data: [[u8; PAGE_BYTES]; PAGES],
    writes: [[u8; PAGE_BYTES]; PAGES],
    erases: [u32; PAGES],
    rule: WriteRule,
    budget: Option<u32>,
    powered: bool,
    bytes_touched: u64,
}

impl<const PAGES: usize, const PAGE_BYTES: usize, const WORD: usize>
    RamFlash<PAGES, PAGE_BYTES, WORD>
{
    /// Total size, bytes.
    pub const CAPACITY: usize = PAGES * PAGE_BYTES;

    const GEOMETRY_OK: () = assert!(
        WORD > 0
            && WORD <= 32
            && PAGES > 0
            && PAGE_BYTES.is_multiple_of(WORD)
            && PAGES * PAGE_BYTES <= 1 << 31,
        "RamFlash: word 1..=32 bytes, page a multiple of the word, at most 2 GiB"
    );

    /// An erased flash (all bytes 0xFF) with the given write rule and no power cut pending.
    pub const fn new(rule: WriteRule) -> Self {
        let () = Self::GEOMETRY_OK;
        RamFlash {
            data: [[0xFF; PAGE_BYTES]; PAGES],
            writes: [[ERASED; PAGE_BYTES]; PAGES],
            erases: [0; PAGES],
            rule,
            budget: None,
            powered: true,
            bytes_touched: 0,
        }
    }

    /// After `bytes` more written or erased bytes, tear the next byte and cut the power.
    /// `None` cancels a pending cut.
    pub fn cut_power_after(&mut self, bytes: Option<u32>) {
        self.budget = bytes;
    }

    /// Powers the flash up again (a reboot): cancels any pending cut; contents stay as they are.
    pub fn restore_power(&mut self) {
        self.powered = true;
        self.budget = None;
    }

    /// True while the power is on.
    pub fn is_powered(&self) -> bool {
        self.powered
    }

    /// Total bytes written or erased so far (the unit of [`Self::cut_power_after`]).
    pub fn bytes_touched(&self) -> u64 {
        self.bytes_touched
    }

    /// How many times each page has been erased.
    pub fn erase_counts(&self) -> [u32; PAGES] {
        self.erases
    }

    /// The byte at `offset`, or `None` outside the flash. Ignores power (a test probe).
    pub fn byte(&self, offset: usize) -> Option<u8> {
        self.data
            .get(offset / PAGE_BYTES)
            .map(|page| page[offset % PAGE_BYTES])
    }

    /// Overwrites the byte at `offset` behind the flash's back (bit rot, stray writes, a test
    /// probe). Write counts are left alone. Returns `false` outside the flash.
    pub fn corrupt_byte(&mut self, offset: usize, value: u8) -> bool {
        match self.data.get_mut(offset / PAGE_BYTES) {
            Some(page) => {
                page[offset % PAGE_BYTES] = value;
                true
            }
            None => false,
        }
    }

    /// Copies the contents into `out` (a flash image, e.g. to keep in a file). Copies
    /// `min(out.len(), CAPACITY)` bytes and returns that count.
    pub fn copy_image(&self, out: &mut [u8]) -> usize {
        let n = out.len().min(Self::CAPACITY);
        for (i, b) in out[..n].iter_mut().enumerate() {
            *b = self.data[i / PAGE_BYTES][i % PAGE_BYTES];
        }
        n
    }

    /// Replaces the contents with an image from [`Self::copy_image`] (missing bytes read as
    /// erased). Words that are not all 0xFF count as written once; wear statistics restart.
    pub fn restore_image(&mut self, image: &[u8]) {
        for i in 0..Self::CAPACITY {
            self.data[i / PAGE_BYTES][i % PAGE_BYTES] = image.get(i).copied().unwrap_or(0xFF);
        }
        for page in 0..PAGES {
            for at in (0..PAGE_BYTES).step_by(WORD) {
                let erased = self.data[page][at..at + WORD].iter().all(|&b| b == 0xFF);
                self.writes[page][at] = if erased { ERASED } else { WRITTEN_ONCE };
            }
        }
        self.erases = [0; PAGES];
    }

    /// Checks alignment and bounds of a word access.
    fn check_words(offset: u32, len: usize) -> Result<usize, RamFlashError> {
        let start = offset as usize;
        if !start.is_multiple_of(WORD) || !len.is_multiple_of(WORD) {
            return Err(RamFlashError::NotAligned);
        }
        match start.checked_add(len) {
            Some(end) if end <= Self::CAPACITY => Ok(start),
            _ => Err(RamFlashError::OutOfBounds),
        }
    }

    /// Spends one byte of the power budget; `false` means the power fails at this byte.
    fn spend_byte(&mut self) -> bool {
        match self.budget {
            Some(0) => {
                self.budget = None;
                self.powered = false;
                false
            }
            Some(n) => {
                self.budget = Some(n - 1);
                self.bytes_touched += 1;
                true
            }
            None => {
                self.bytes_touched += 1;
                true
            }
        }
    }

    fn check_power(&self) -> Result<(), RamFlashError> {
        if self.powered {
            Ok(())
        } else {
            Err(RamFlashError::PowerCut)
        }
    }

    /// Programs one word at `addr` (word aligned, in bounds).
    fn program_word(&mut self, addr: usize, word: &[u8]) -> Result<(), RamFlashError> {
        let (page, at) = (addr / PAGE_BYTES, addr % PAGE_BYTES);
        let count = self.writes[page][at];
        let all_zero = word.iter().all(|&b| b == 0);
        let allowed = match (count, self.rule) {
            (ERASED, _) => true,
            (WRITTEN_ONCE, WriteRule::TwiceWithZero) => all_zero,
            _ => false,
        };
        if !allowed {
            return Err(RamFlashError::WrittenTwice(addr as u32));
        }
        let old = &self.data[page][at..at + WORD];
        if old.iter().zip(word).any(|(&o, &n)| n & !o != 0) {
            return Err(RamFlashError::ZeroToOne(addr as u32));
        }
        let mut before = [0xFFu8; 32];
        let keep = WORD.min(before.len());
        before[..keep].copy_from_slice(&self.data[page][at..at + keep]);
        self.writes[page][at] = if count == ERASED {
            WRITTEN_ONCE
        } else {
            WRITTEN_TWICE
        };
        for (i, &new) in word.iter().enumerate() {
            if !self.spend_byte() {
                // Torn byte: only the zero bits of its low nibble get programmed.
                self.data[page][at + i] &= new | 0xF0;
                // A program operation that changed no bit leaves no trace (no ECC): the word
                // stays as writable as it was. Otherwise its write is used up.
                if self.data[page][at..at + keep] == before[..keep] {
                    self.writes[page][at] = count;
                }
                return Err(RamFlashError::PowerCut);
            }
            self.data[page][at + i] &= new;
        }
        Ok(())
    }
}

impl<const PAGES: usize, const PAGE_BYTES: usize, const WORD: usize> Default
    for RamFlash<PAGES, PAGE_BYTES, WORD>
{
    /// An erased flash with the STM32 rule [`WriteRule::TwiceWithZero`].
    fn default() -> Self {
        Self::new(WriteRule::TwiceWithZero)
    }
}

impl<const PAGES: usize, const PAGE_BYTES: usize, const WORD: usize> fmt::Debug
    for RamFlash<PAGES, PAGE_BYTES, WORD>
{
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RamFlash")
            .field("pages", &PAGES)
            .field("page_bytes", &PAGE_BYTES)
            .field("word", &WORD)
            .field("rule", &self.rule)
            .field("erases", &self.erases.as_slice())
            .field("powered", &self.powered)
            .finish_non_exhaustive()
    }
}

impl<const PAGES: usize, const PAGE_BYTES: usize, const WORD: usize> ErrorType
    for RamFlash<PAGES, PAGE_BYTES, WORD>
{
    type Error = RamFlashError;
}

impl<const PAGES: usize, const PAGE_BYTES: usize, const WORD: usize> ReadNorFlash
    for RamFlash<PAGES, PAGE_BYTES, WORD>
{
    const READ_SIZE: usize = WORD;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.check_power()?;
        let mut addr = Self::check_words(offset, bytes.len())?;
        let mut out = bytes;
        while !out.is_empty() {
            let (page, at) = (addr / PAGE_BYTES, addr % PAGE_BYTES);
            let n = out.len().min(PAGE_BYTES - at);
            let (head, tail) = out.split_at_mut(n);
            head.copy_from_slice(&self.data[page][at..at + n]);
            out = tail;
            addr += n;
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        Self::CAPACITY
    }
}

impl<const PAGES: usize, const PAGE_BYTES: usize, const WORD: usize> NorFlash
    for RamFlash<PAGES, PAGE_BYTES, WORD>
{
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE_BYTES;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.check_power()?;
        let (from, to) = (from as usize, to as usize);
        if from > to || to > Self::CAPACITY {
            return Err(RamFlashError::OutOfBounds);
        }
        if !from.is_multiple_of(PAGE_BYTES) || !to.is_multiple_of(PAGE_BYTES) {
            return Err(RamFlashError::NotAligned);
        }
        for page in from / PAGE_BYTES..to / PAGE_BYTES {
            self.erases[page] += 1;
            for at in 0..PAGE_BYTES {
                if !self.spend_byte() {
                    // Torn byte: only its low nibble is erased; later bytes keep old contents
                    // and the page keeps the write counts of a programmed page.
                    self.data[page][at] |= 0x0F;
                    return Err(RamFlashError::PowerCut);
                }
                self.data[page][at] = 0xFF;
                self.writes[page][at] = ERASED;
            }
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.check_power()?;
        let start = Self::check_words(offset, bytes.len())?;
        for (i, word) in bytes.chunks_exact(WORD).enumerate() {
            self.program_word(start + i * WORD, word)?;
        }
        Ok(())
    }
}

/// Multiple writes to a word are allowed as far as the [`WriteRule`] says (with
/// [`WriteRule::TwiceWithZero`]: a second write of zeros, which is how `sequential-storage`
/// marks items and pages). With [`WriteRule::Once`] this marker over-promises and the flash
/// reports [`RamFlashError::WrittenTwice`] instead.
impl<const PAGES: usize, const PAGE_BYTES: usize, const WORD: usize> MultiwriteNorFlash
    for RamFlash<PAGES, PAGE_BYTES, WORD>
{
}

#[cfg(test)]
mod tests {
    use embassy_futures::block_on;

    use super::*;

    type Small = RamFlash<2, 64, 4>;

    #[test]
    fn enforces_alignment_and_bounds() {
        let mut f = Small::default();
        let mut buf = [0u8; 4];
        assert_eq!(
            block_on(f.read(2, &mut buf)),
            Err(RamFlashError::NotAligned)
        );
        assert_eq!(
            block_on(f.write(4, &[0; 3])),
            Err(RamFlashError::NotAligned)
        );
        assert_eq!(
            block_on(f.write(128, &[0; 4])),
            Err(RamFlashError::OutOfBounds)
        );
        assert_eq!(block_on(f.erase(0, 32)), Err(RamFlashError::NotAligned));
        assert_eq!(block_on(f.erase(64, 0)), Err(RamFlashError::OutOfBounds));
        assert_eq!(block_on(f.erase(0, 192)), Err(RamFlashError::OutOfBounds));
    }

    #[test]
    fn writes_only_clear_bits_and_respect_the_write_rule() {
        let mut f = Small::new(WriteRule::TwiceWithZero);
        block_on(f.write(8, &[0xF0, 0x0F, 0xAA, 0x55])).unwrap();
        let mut buf = [0u8; 4];
        block_on(f.read(8, &mut buf)).unwrap();
        assert_eq!(buf, [0xF0, 0x0F, 0xAA, 0x55]);
        // A second non-zero write is refused even though it only clears bits.
        assert_eq!(
            block_on(f.write(8, &[0x00, 0x0F, 0xAA, 0x55])),
            Err(RamFlashError::WrittenTwice(8))
        );
        // A second write of zeros is the STM32 exception.
        block_on(f.write(8, &[0; 4])).unwrap();
        assert_eq!(
            block_on(f.write(8, &[0; 4])),
            Err(RamFlashError::WrittenTwice(8))
        );
        // Under `Once`, even zeros may not be written twice.
        let mut once = Small::new(WriteRule::Once);
        block_on(once.write(0, &[0x12; 4])).unwrap();
        assert_eq!(
            block_on(once.write(0, &[0; 4])),
            Err(RamFlashError::WrittenTwice(0))
        );
        // Only an erase turns 0 bits back into 1 bits; it works per page.
        block_on(f.erase(0, 64)).unwrap();
        block_on(f.read(8, &mut buf)).unwrap();
        assert_eq!(buf, [0xFF; 4]);
        assert_eq!(f.erase_counts(), [1, 0]);
    }

    #[test]
    fn zero_to_one_is_an_error() {
        let mut f = Small::new(WriteRule::TwiceWithZero);
        // Bit rot left a zero in an erased word; programming a 1 there cannot work.
        assert!(f.corrupt_byte(4, 0x7F));
        assert_eq!(
            block_on(f.write(4, &[0xFF, 0xFF, 0xFF, 0xFF])),
            Err(RamFlashError::ZeroToOne(4))
        );
    }

    #[test]
    fn power_cut_tears_the_next_byte_and_stops_everything() {
        let mut f = Small::default();
        f.cut_power_after(Some(5));
        assert_eq!(
            block_on(f.write(0, &[0x00; 8])),
            Err(RamFlashError::PowerCut)
        );
        // 5 bytes written, byte 5 half programmed (low nibble cleared), bytes 6.. untouched.
        let got: [u8; 8] = core::array::from_fn(|i| f.byte(i).unwrap());
        assert_eq!(got, [0, 0, 0, 0, 0, 0xF0, 0xFF, 0xFF]);
        let mut buf = [0u8; 4];
        assert_eq!(block_on(f.read(0, &mut buf)), Err(RamFlashError::PowerCut));
        f.restore_power();
        block_on(f.read(4, &mut buf)).unwrap();
        assert_eq!(buf, [0, 0xF0, 0xFF, 0xFF]);
        // The torn word has used its write; only zeros may follow.
        assert_eq!(
            block_on(f.write(4, &[0, 0, 0x12, 0x34])),
            Err(RamFlashError::WrittenTwice(4))
        );

        // A torn erase leaves the page partially erased.
        f.cut_power_after(Some(3));
        assert_eq!(block_on(f.erase(0, 64)), Err(RamFlashError::PowerCut));
        f.restore_power();
        let got: [u8; 6] = core::array::from_fn(|i| f.byte(i).unwrap());
        assert_eq!(got, [0xFF, 0xFF, 0xFF, 0x0F, 0x00, 0xF0]);
    }

    #[test]
    fn a_torn_write_that_changed_nothing_leaves_the_word_writable() {
        let mut f = RamFlash::<2, 64, 1>::default();
        // Byte 0 is cut at once; its target 0x0F has an all-ones low nibble, so nothing changed.
        f.cut_power_after(Some(0));
        assert_eq!(block_on(f.write(0, &[0x0F])), Err(RamFlashError::PowerCut));
        f.restore_power();
        assert_eq!(f.byte(0), Some(0xFF));
        block_on(f.write(0, &[0x12])).unwrap();
        // Byte 1's target 0xF0 does change its low nibble: the write is used up.
        f.cut_power_after(Some(0));
        assert_eq!(block_on(f.write(1, &[0xF0])), Err(RamFlashError::PowerCut));
        f.restore_power();
        assert_eq!(f.byte(1), Some(0xF0));
        assert_eq!(
            block_on(f.write(1, &[0xF0])),
            Err(RamFlashError::WrittenTwice(1))
        );
    }

    #[test]
    fn images_round_trip_and_keep_words_written() {
        let mut a = Small::default();
        block_on(a.write(4, &[1, 2, 3, 4])).unwrap();
        let mut image = [0u8; 128];
        assert_eq!(a.copy_image(&mut image), 128);
        let mut b = Small::default();
        b.restore_image(&image);
        assert_eq!(b.byte(5), Some(2));
        assert_eq!(b.byte(8), Some(0xFF));
        // The programmed word is not blank any more; an erased one still is.
        assert_eq!(
            block_on(b.write(4, &[1, 2, 3, 4])),
            Err(RamFlashError::WrittenTwice(4))
        );
        block_on(b.write(8, &[9; 4])).unwrap();
    }

    #[test]
    fn clones_are_independent_and_keep_everything() {
        let mut a = Small::default();
        block_on(a.write(0, &[1, 2, 3, 4])).unwrap();
        let mut b = a.clone();
        block_on(b.erase(0, 64)).unwrap();
        assert_eq!(a.byte(0), Some(1));
        assert_eq!(b.byte(0), Some(0xFF));
        assert_eq!(a.erase_counts(), [0, 0]);
        assert_eq!(b.erase_counts(), [1, 0]);
        assert_eq!(a.bytes_touched(), 4);
    }
}
