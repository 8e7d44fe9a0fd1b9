//! ARM semihosting file access (QEMU `-semihosting-config enable=on,target=native`): the
//! emulator's parameter flash lives in a file on the host, so it survives a restart of the
//! emulator like the board's flash survives a reset.

use core::arch::asm;

const SYS_OPEN: u32 = 0x01;
const SYS_WRITE: u32 = 0x05;
const SYS_READ: u32 = 0x06;
const SYS_SEEK: u32 = 0x0A;
const SYS_FLEN: u32 = 0x0C;
/// `fopen` mode "r+b": read and write an existing file.
const MODE_READ_WRITE_BINARY: u32 = 3;

/// One semihosting call: operation `op`, parameter block `args`.
fn call(op: u32, args: &[u32]) -> i32 {
    let result: i32;
    // SAFETY: `bkpt 0xab` is the semihosting trap, which QEMU handles (with semihosting enabled,
    // as the emulator build is always run). The parameter block lives on the caller's stack for
    // the duration of the call and QEMU only reads it; buffers named in it are valid for their
    // stated lengths (see the callers).
    unsafe {
        asm!("bkpt #0xab", inout("r0") op => result, in("r1") args.as_ptr(), options(nostack));
    }
    result
}

/// An open host file.
pub struct HostFile {
    handle: u32,
}

impl HostFile {
    /// Opens the existing file `path` (NUL-terminated) for reading and writing.
    pub fn open(path: &core::ffi::CStr) -> Option<HostFile> {
        let bytes = path.to_bytes();
        let handle = call(
            SYS_OPEN,
            &[
                bytes.as_ptr() as u32,
                MODE_READ_WRITE_BINARY,
                bytes.len() as u32,
            ],
        );
        u32::try_from(handle).ok().map(|handle| HostFile { handle })
    }

    /// The file's size in bytes.
    pub fn size(&self) -> Option<u32> {
        u32::try_from(call(SYS_FLEN, &[self.handle])).ok()
    }

    fn seek(&self, offset: u32) -> bool {
        call(SYS_SEEK, &[self.handle, offset]) == 0
    }

    /// Reads `buf.len()` bytes at `offset`; false unless all were read.
    pub fn read_at(&self, offset: u32, buf: &mut [u8]) -> bool {
        self.seek(offset)
            && call(
                SYS_READ,
                &[self.handle, buf.as_mut_ptr() as u32, buf.len() as u32],
            ) == 0
    }

    /// Writes `buf` at `offset`; false unless all were written.
    pub fn write_at(&self, offset: u32, buf: &[u8]) -> bool {
        self.seek(offset)
            && call(
                SYS_WRITE,
                &[self.handle, buf.as_ptr() as u32, buf.len() as u32],
            ) == 0
    }
}
