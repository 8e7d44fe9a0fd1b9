//! What the last panic or HardFault was, kept across the reset that follows it.
//!
//! The fault handlers stop the motors and reset the MCU at once; a log line sent through RTT just
//! before rarely reaches a host. So the handler also writes a [`CrashRecord`] into a RAM region
//! the startup code does not initialise (the board's `.uninit` section), and the next boot reads
//! it back: the boot line then says `reset: panic at src/…:line` instead of `software`.
//!
//! The region holds garbage after a power-on, so the record carries a magic word and a checksum
//! over every other word; anything that does not check out is no record. Reading takes the record
//! (the region is invalidated), so a later reset for another reason is not blamed on it.

use core::fmt;

/// Words of the stored form.
pub const WORDS: usize = 16;
/// Longest file name kept, bytes (the end of a longer one: the part that names the module).
pub const FILE_LEN: usize = 4 * (WORDS - 5);

/// `odoC` in ASCII, and the version of the layout.
const MAGIC: u32 = 0x6f64_6f43 ^ 1;

/// Which handler wrote the record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrashKind {
    /// A Rust panic: the record has its file and line.
    Panic,
    /// A HardFault: the record has the faulting instruction's address.
    HardFault,
}

/// The last fault before a reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CrashRecord {
    /// Which handler.
    pub kind: CrashKind,
    /// Source line of the panic (0 for a HardFault).
    pub line: u32,
    /// Program counter of the HardFault (0 for a panic).
    pub pc: u32,
    file: [u8; FILE_LEN],
    file_len: u8,
}

impl CrashRecord {
    /// A panic at `file:line` (the last [`FILE_LEN`] bytes of a longer name are kept).
    pub fn panic(file: &str, line: u32) -> Self {
        let bytes = file.as_bytes();
        let tail = &bytes[bytes.len().saturating_sub(FILE_LEN)..];
        let mut stored = [0u8; FILE_LEN];
        stored[..tail.len()].copy_from_slice(tail);
        CrashRecord {
            kind: CrashKind::Panic,
            line,
            pc: 0,
            file: stored,
            file_len: tail.len() as u8,
        }
    }

    /// A HardFault at `pc`.
    pub fn hard_fault(pc: u32) -> Self {
        CrashRecord {
            kind: CrashKind::HardFault,
            line: 0,
            pc,
            file: [0; FILE_LEN],
            file_len: 0,
        }
    }

    /// The panic's file name (empty for a HardFault; a name cut inside a UTF-8 sequence loses
    /// the cut character).
    pub fn file(&self) -> &str {
        let bytes = &self.file[..usize::from(self.file_len)];
        match core::str::from_utf8(bytes) {
            Ok(s) => s,
            Err(e) => core::str::from_utf8(&bytes[e.valid_up_to()..]).unwrap_or(""),
        }
    }

    /// The stored form.
    pub fn encode(&self) -> [u32; WORDS] {
        let mut w = [0u32; WORDS];
        w[1] = match self.kind {
            CrashKind::Panic => 1,
            CrashKind::HardFault => 2,
        };
        w[2] = self.line;
        w[3] = self.pc;
        w[4] = u32::from(self.file_len);
        for (i, chunk) in self.file.chunks_exact(4).enumerate() {
            w[5 + i] = u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
        }
        w[0] = MAGIC ^ checksum(&w[1..]);
        w
    }

    /// The record in `words`, if they hold one.
    pub fn decode(words: &[u32; WORDS]) -> Option<Self> {
        if words[0] != MAGIC ^ checksum(&words[1..]) {
            return None;
        }
        let kind = match words[1] {
            1 => CrashKind::Panic,
            2 => CrashKind::HardFault,
            _ => return None,
        };
        let file_len = u8::try_from(words[4])
            .ok()
            .filter(|&n| usize::from(n) <= FILE_LEN)?;
        let mut file = [0u8; FILE_LEN];
        for (i, chunk) in file.chunks_exact_mut(4).enumerate() {
            chunk.copy_from_slice(&words[5 + i].to_le_bytes());
        }
        Some(CrashRecord {
            kind,
            line: words[2],
            pc: words[3],
            file,
            file_len,
        })
    }
}

/// A word that no erased, zeroed or random region gives by chance more than once in 2^32:
/// FNV-1a over the bytes.
fn checksum(words: &[u32]) -> u32 {
    let mut h: u32 = 0x811c_9dc5;
    for w in words {
        for b in w.to_le_bytes() {
            h ^= u32::from(b);
            h = h.wrapping_mul(0x0100_0193);
        }
    }
    h
}

/// `panic at FILE:LINE` or `hard fault at pc 0x…`: the boot line's reset cause.
impl fmt::Display for CrashRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.kind {
            CrashKind::Panic => write!(f, "panic at {}:{}", self.file(), self.line),
            CrashKind::HardFault => write!(f, "hard fault at pc {:#010x}", self.pc),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_survives_its_stored_form() {
        let r = CrashRecord::panic("src/session/mod.rs", 321);
        let back = CrashRecord::decode(&r.encode());
        assert_eq!(back, Some(r));
        assert_eq!(
            back.map(|r| std::format!("{r}")).as_deref(),
            Some("panic at src/session/mod.rs:321")
        );
    }

    #[test]
    fn a_hard_fault_names_its_address() {
        let r = CrashRecord::hard_fault(0x0800_1234);
        assert_eq!(
            CrashRecord::decode(&r.encode()).map(|r| std::format!("{r}")),
            Some("hard fault at pc 0x08001234".into())
        );
    }

    #[test]
    fn a_long_file_name_keeps_its_end() {
        let long = "a/very/long/path/that/does/not/fit/into/the/record/src/motion/routine.rs";
        let r = CrashRecord::decode(&CrashRecord::panic(long, 7).encode());
        let file = r.map(|r| std::string::String::from(r.file()));
        assert_eq!(file.as_deref(), Some(&long[long.len() - FILE_LEN..]));
    }

    #[test]
    fn power_on_garbage_zeros_and_erased_ram_hold_no_record() {
        assert_eq!(CrashRecord::decode(&[0; WORDS]), None);
        assert_eq!(CrashRecord::decode(&[u32::MAX; WORDS]), None);
        // A pseudo-random fill, as SRAM wakes up.
        let mut x = 0x1234_5678u32;
        for _ in 0..1000 {
            let mut w = [0u32; WORDS];
            for v in &mut w {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                *v = x;
            }
            assert_eq!(CrashRecord::decode(&w), None);
        }
    }

    #[test]
    fn one_flipped_bit_anywhere_invalidates_the_record() {
        let good = CrashRecord::panic("src/main.rs", 42).encode();
        for word in 0..WORDS {
            for bit in 0..32 {
                let mut w = good;
                w[word] ^= 1 << bit;
                assert_eq!(CrashRecord::decode(&w), None, "word {word} bit {bit}");
            }
        }
    }
}
