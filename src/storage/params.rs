//! The parameter region: two erase sectors used A/B, each a log of parameter records, apart
//! from the run region (its own `sequential-storage` map), so nothing done to the runs can
//! touch the parameters.
//!
//! Each save appends one **slot** to the sector that holds the newest valid record; when that
//! sector has no room, the *other* sector is erased and the slot goes there. The sector with
//! the newest valid record is never erased, so no path (save, power cut during a save, damaged
//! contents) can lose the last valid record; loading only reads.
//!
//! | slot | offset | size |
//! |---|---|---|
//! | data length `n` (u16) | 0 | 2 |
//! | `!n` (u16): a torn or blank length is told from a real one | 2 | 2 |
//! | sequence number (u32), +1 per save | 4 | 4 |
//! | CRC-32 (IEEE) of bytes 0..8 and the data | 8 | 4 |
//! | the data (the encoded [`super::ParamRecord`]) | 12 | n |
//! | 0xFF up to the flash word | | |
//!
//! Reading a sector: slots are walked from its start; an erased header (all 0xFF) starts the
//! free space, which must be erased up to the sector's end to be used; a header whose two
//! length fields disagree (torn, or not a slot at all) ends the walk with no free space; a slot
//! whose CRC fails is skipped. The newest valid record is the slot with the highest sequence
//! number in either sector.
//!
//! Power cuts (`tests/storage_power_cut.rs` cuts at every byte): a torn slot fails its CRC and
//! the previous record stays the newest; a torn erase only ever hits the sector that does not
//! hold the newest record, and that sector is erased again before it is written.

use core::ops::Range;

use embedded_storage_async::nor_flash::MultiwriteNorFlash;

use super::StoreError;

/// Slot header length, bytes.
pub const HEADER: usize = 12;
/// Bytes read per flash access while walking a sector (a multiple of every word size).
const CHUNK: usize = 32;
/// Largest data length a slot header can describe.
const MAX_DATA: usize = 0xFFFE;

/// The parameter region's two sectors (byte offsets in the store's flash, each one whole erase
/// unit of it).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamSectors {
    /// The sectors, in address order.
    pub sectors: [Range<u32>; 2],
}

impl ParamSectors {
    /// Two sectors; checked when the store is built (`ParamAndRunStore::new`) or, for a `const`
    /// layout, when the firmware is built.
    pub const fn new(a: Range<u32>, b: Range<u32>) -> Self {
        ParamSectors { sectors: [a, b] }
    }

    /// Whether the sectors can hold the parameters with flash words of `align` bytes:
    /// non-empty, word aligned, apart, each room for one slot of `data_max` bytes.
    pub const fn valid(&self, align: usize, data_max: usize) -> bool {
        let [a, b] = &self.sectors;
        let slot = slot_len(data_max, align) as u32;
        let align = align as u32;
        a.start.is_multiple_of(align)
            && a.end.is_multiple_of(align)
            && b.start.is_multiple_of(align)
            && b.end.is_multiple_of(align)
            && a.start < a.end
            && b.start < b.end
            && a.end - a.start >= slot
            && b.end - b.start >= slot
            && (a.end <= b.start || b.end <= a.start)
    }

    /// Whether `range` overlaps either sector.
    pub const fn overlaps(&self, range: &Range<u32>) -> bool {
        let [a, b] = &self.sectors;
        (range.start < a.end && a.start < range.end) || (range.start < b.end && b.start < range.end)
    }
}

/// Bytes a slot of `data` bytes takes with flash words of `align` bytes.
pub const fn slot_len(data: usize, align: usize) -> usize {
    (HEADER + data).next_multiple_of(align)
}

/// Flash word of `F` for slots: writes and reads both aligned.
pub const fn align_of<F: MultiwriteNorFlash>() -> usize {
    if F::WRITE_SIZE > F::READ_SIZE {
        F::WRITE_SIZE
    } else {
        F::READ_SIZE
    }
}

/// A valid slot found in a sector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot {
    /// Which sector (0 or 1).
    pub sector: usize,
    /// Offset of the slot's header.
    pub at: u32,
    /// Data length.
    pub len: usize,
    /// Sequence number.
    pub seq: u32,
}

/// What a walk over both sectors found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Scan {
    /// The newest valid slot.
    pub newest: Option<Slot>,
    /// The valid slot before it (in either sector): the record to fall back to when the
    /// newest one does not decode or validate.
    pub previous: Option<Slot>,
    /// Per sector: where its erased free space starts (erased to the sector's end), if it has any.
    pub free: [Option<u32>; 2],
    /// Per sector: whether any byte is programmed.
    pub dirty: [bool; 2],
    /// Per sector: whether it holds something other than slots (its first bytes are neither
    /// erased nor a slot header: an older firmware's program code, which these sectors held
    /// before the parameters moved here).
    pub foreign: [bool; 2],
}

impl Scan {
    /// No slot was ever written to the region: each sector is erased or holds something else
    /// from its first byte on (the first save erases it).
    pub fn never_written(&self) -> bool {
        (0..2).all(|i| !self.dirty[i] || self.foreign[i])
    }
}

/// CRC-32 (IEEE 802.3, reflected, as zlib) over `bytes`, continuing from `crc` (start with
/// `!0`, finish with `!`). Bitwise: a few hundred bytes per save, no table in flash.
fn crc32(mut crc: u32, bytes: &[u8]) -> u32 {
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = (crc >> 1) ^ (0xEDB8_8320 & (crc & 1).wrapping_neg());
        }
    }
    crc
}

fn header_fields(h: &[u8; HEADER]) -> (u16, u16, u32, u32) {
    let [l0, l1, c0, c1, s0, s1, s2, s3, k0, k1, k2, k3] = *h;
    (
        u16::from_le_bytes([l0, l1]),
        u16::from_le_bytes([c0, c1]),
        u32::from_le_bytes([s0, s1, s2, s3]),
        u32::from_le_bytes([k0, k1, k2, k3]),
    )
}

/// Reads `range` in chunks, calling `each` with every chunk (the last one may be shorter;
/// `dyn`: one copy of the reading code whatever the caller does with the bytes).
async fn read_chunks<F: MultiwriteNorFlash>(
    flash: &mut F,
    range: Range<u32>,
    each: &mut dyn FnMut(&[u8]),
) -> Result<(), StoreError> {
    let mut chunk = [0u8; CHUNK];
    let mut at = range.start;
    while at < range.end {
        let n = ((range.end - at) as usize).min(CHUNK);
        let part = &mut chunk[..n];
        flash.read(at, part).await.map_err(flash_error::<F>)?;
        each(part);
        at += n as u32;
    }
    Ok(())
}

fn flash_error<F: MultiwriteNorFlash>(e: F::Error) -> StoreError {
    use embedded_storage_async::nor_flash::NorFlashError;
    StoreError::Flash(e.kind().into())
}

/// Walks one sector: its newest valid slot, where its free space starts, whether it is dirty,
/// whether its first bytes are something other than a slot (see [`Scan::foreign`]).
async fn scan_sector<F: MultiwriteNorFlash>(
    flash: &mut F,
    sector: usize,
    range: &Range<u32>,
    data_max: usize,
) -> Result<([Option<Slot>; 2], Option<u32>, bool, bool), StoreError> {
    let align = align_of::<F>();
    let header_read = HEADER.next_multiple_of(align);
    // The newest two valid slots, newest first.
    let mut newest: [Option<Slot>; 2] = [None, None];
    let mut at = range.start;
    let mut dirty = false;
    let mut foreign = false;
    let free = loop {
        if (range.end - at) as usize <= header_read {
            // No room for another slot header: whatever is left is not free space.
            let mut rest_dirty = false;
            read_chunks(flash, at..range.end, &mut |c| {
                rest_dirty |= c.iter().any(|&b| b != 0xFF);
            })
            .await?;
            dirty |= rest_dirty;
            break None;
        }
        let mut head = [0u8; HEADER];
        let mut got = 0;
        read_chunks(flash, at..at + header_read as u32, &mut |c| {
            let n = c.len().min(HEADER - got);
            head[got..got + n].copy_from_slice(&c[..n]);
            got += n;
        })
        .await?;
        let (len, check, seq, crc) = header_fields(&head);
        if head.iter().all(|&b| b == 0xFF) {
            // Free from here if erased to the sector's end.
            let mut rest_dirty = false;
            read_chunks(flash, at..range.end, &mut |c| {
                rest_dirty |= c.iter().any(|&b| b != 0xFF);
            })
            .await?;
            dirty |= rest_dirty;
            break (!rest_dirty).then_some(at);
        }
        dirty = true;
        let len = usize::from(len);
        let slot = slot_len(len, align) as u32;
        if len ^ usize::from(check) != 0xFFFF || len > data_max || slot > range.end - at {
            // Not a slot (torn header, garbage): the rest of the sector is unusable. At the
            // sector's start it never held slots.
            foreign = at == range.start;
            break None;
        }
        // The whole slot from its (aligned) start: the CRC covers bytes 0..8 and the data.
        let mut sum = !0;
        let mut pos = 0usize;
        read_chunks(flash, at..at + slot, &mut |c| {
            for &b in c {
                if pos < 8 || (HEADER..HEADER + len).contains(&pos) {
                    sum = crc32(sum, &[b]);
                }
                pos += 1;
            }
        })
        .await?;
        if !sum == crc {
            keep_newest(
                &mut newest,
                Slot {
                    sector,
                    at,
                    len,
                    seq,
                },
            );
        }
        at += slot;
    };
    Ok((newest, free, dirty, foreign))
}

/// Keeps the two newest of `top` and `slot` in `top`, newest first.
fn keep_newest(top: &mut [Option<Slot>; 2], slot: Slot) {
    if top[0].is_none_or(|n| slot.seq > n.seq) {
        top[1] = top[0];
        top[0] = Some(slot);
    } else if top[1].is_none_or(|n| slot.seq > n.seq) {
        top[1] = Some(slot);
    }
}

/// Walks both sectors.
///
/// # Errors
/// [`StoreError::Flash`] if a read fails.
pub async fn scan<F: MultiwriteNorFlash>(
    flash: &mut F,
    sectors: &ParamSectors,
    data_max: usize,
) -> Result<Scan, StoreError> {
    let mut out = Scan::default();
    let mut top = [None, None];
    for (i, range) in sectors.sectors.iter().enumerate() {
        let (found, free, dirty, foreign) = scan_sector(flash, i, range, data_max).await?;
        out.free[i] = free;
        out.dirty[i] = dirty;
        out.foreign[i] = foreign;
        for slot in found.into_iter().flatten() {
            keep_newest(&mut top, slot);
        }
    }
    [out.newest, out.previous] = top;
    Ok(out)
}

/// Reads `slot` into the start of `buf` (at least `slot_len(slot.len)` bytes) and returns its
/// data (`buf[HEADER..]`).
///
/// # Errors
/// [`StoreError::Flash`] if the read fails, [`StoreError::Encoding`] if `buf` is too short.
pub async fn read<'b, F: MultiwriteNorFlash>(
    flash: &mut F,
    slot: &Slot,
    buf: &'b mut [u8],
) -> Result<&'b [u8], StoreError> {
    let align = align_of::<F>();
    let whole = slot_len(slot.len, align);
    let Some(area) = buf.get_mut(..whole) else {
        return Err(StoreError::Encoding);
    };
    flash.read(slot.at, area).await.map_err(flash_error::<F>)?;
    Ok(&buf[HEADER..HEADER + slot.len])
}

/// Appends a record whose `len` data bytes are at `buf[HEADER..]` (`buf` holds at least
/// `slot_len(len)` bytes; its header and padding are overwritten). Returns the new slot.
///
/// Into the free space of the sector with the newest valid record if it fits there, else into
/// the other sector, erased first (with no valid record anywhere: into a sector's free space,
/// else sector 0 erased). The slot is read back and checked.
///
/// # Errors
/// [`StoreError::Flash`] for a driver error, [`StoreError::Encoding`] if the record does not
/// fit a sector or `buf`, [`StoreError::Corrupted`] if the written slot does not read back.
pub async fn append<F: MultiwriteNorFlash>(
    flash: &mut F,
    sectors: &ParamSectors,
    buf: &mut [u8],
    len: usize,
    data_max: usize,
) -> Result<Slot, StoreError> {
    let align = align_of::<F>();
    let whole = slot_len(len, align);
    if len > data_max.min(MAX_DATA) || buf.len() < whole {
        return Err(StoreError::Encoding);
    }
    let found = scan(flash, sectors, data_max).await?;
    let fits = |i: usize| {
        found.free[i]
            .filter(|&at| u64::from(at) + whole as u64 <= u64::from(sectors.sectors[i].end))
    };
    let target = match found.newest {
        Some(n) => fits(n.sector).map(|at| (n.sector, at, false)),
        None => (0..2).find_map(|i| fits(i).map(|at| (i, at, false))),
    };
    let (sector, at, erase) = target.unwrap_or_else(|| {
        let other = found.newest.map_or(0, |n| 1 - n.sector);
        (other, sectors.sectors[other].start, true)
    });
    let range = &sectors.sectors[sector];
    if whole as u64 > u64::from(range.end - range.start) {
        return Err(StoreError::Encoding);
    }
    if erase {
        // Never the sector with the newest valid record (it is the other one).
        flash
            .erase(range.start, range.end)
            .await
            .map_err(flash_error::<F>)?;
    }
    let seq = found.newest.map_or(1, |n| n.seq.wrapping_add(1));
    let n = len as u16;
    let mut head = [0u8; HEADER];
    head[0..2].copy_from_slice(&n.to_le_bytes());
    head[2..4].copy_from_slice(&(!n).to_le_bytes());
    head[4..8].copy_from_slice(&seq.to_le_bytes());
    let crc = !crc32(crc32(!0, &head[..8]), &buf[HEADER..HEADER + len]);
    head[8..12].copy_from_slice(&crc.to_le_bytes());
    buf[..HEADER].copy_from_slice(&head);
    buf[HEADER + len..whole].fill(0xFF);
    flash
        .write(at, &buf[..whole])
        .await
        .map_err(flash_error::<F>)?;
    // Read back: every byte as written.
    let written = &buf[..whole];
    let mut same = true;
    let mut got = 0usize;
    read_chunks(flash, at..at + whole as u32, &mut |c| {
        same &= written.get(got..got + c.len()) == Some(c);
        got += c.len();
    })
    .await?;
    if !same {
        return Err(StoreError::Corrupted);
    }
    Ok(Slot {
        sector,
        at,
        len,
        seq,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_is_the_ieee_one() {
        // The standard check value of CRC-32/ISO-HDLC.
        assert_eq!(!crc32(!0, b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn sectors_are_checked() {
        let ok = ParamSectors::new(0..1024, 1024..2048);
        assert!(ok.valid(4, 166));
        assert!(!ParamSectors::new(0..1024, 512..2048).valid(4, 166));
        assert!(!ParamSectors::new(0..100, 1024..2048).valid(4, 166));
        assert!(!ParamSectors::new(2..1026, 1026..2050).valid(4, 166));
        assert!(ok.overlaps(&(1000..1100)));
        assert!(!ok.overlaps(&(2048..4096)));
    }
}
