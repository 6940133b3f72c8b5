//! The bank region's flash (sectors 10 and 11), for the link's bank writer.
//!
//! Erasing a 128 KB sector takes 1-2 s, and while it runs every flash read stalls,
//! instruction fetches and vector fetches included. The independent watchdog cannot
//! be stopped and is set to 50 ms. So the erase is started and waited for by a
//! function that lives in RAM ([`erase_in_ram`]), with interrupts off, feeding the
//! watchdog while it polls the busy flag: nothing fetches from flash until the erase
//! is done. The outputs sit at 0 A throughout: an upload is refused while anything
//! plays and locks the bank out of playback first (`link::Control::Lock`), and the
//! timers hold the last (idle) compare values in hardware. The 1 kHz tick pauses for
//! the erase and resumes with the pending update; embassy's clock (TIM2) falls behind
//! by the erase's length, which only delays the async tasks' timers.
//!
//! Programming a word takes about 16 us (x32), during which a fetch from flash
//! stalls as long: done from flash code, with interrupts on.

use core::ptr::{read_volatile, write_volatile};

use sleeve_firmware::link::bank::{Flash, FlashError, SECTOR_LEN};
use touch_protocol::bank::{REGION_ADDR, REGION_LEN};

const FLASH_BASE: usize = 0x4002_3C00;
const ACR: *mut u32 = FLASH_BASE as *mut u32;
const KEYR: *mut u32 = (FLASH_BASE + 0x04) as *mut u32;
const SR: *mut u32 = (FLASH_BASE + 0x0C) as *mut u32;
const CR: *mut u32 = (FLASH_BASE + 0x10) as *mut u32;
const IWDG_KR: *mut u32 = 0x4000_3000 as *mut u32;

const CR_PG: u32 = 1 << 0;
const CR_SER: u32 = 1 << 1;
const CR_PSIZE_X32: u32 = 2 << 8;
const CR_STRT: u32 = 1 << 16;
const CR_LOCK: u32 = 1 << 31;
const SR_BSY: u32 = 1 << 16;
/// OPERR, WRPERR, PGAERR, PGPERR, PGSERR.
const SR_ERRORS: u32 = 0b1111_0010;
const ACR_DCEN: u32 = 1 << 10;
const ACR_DCRST: u32 = 1 << 12;

/// The first sector of the bank region (0x080C0000).
const FIRST_SECTOR: u32 = 10;

/// The bank region's flash.
pub struct BankFlash(());

impl BankFlash {
    /// The only one: the link's bank writer owns it.
    pub fn new() -> Self {
        BankFlash(())
    }
}

/// Starts the erase of sector `snb` and waits for it, feeding the watchdog; returns
/// the status register. Lives in RAM (`.data`, copied there at reset) and calls
/// nothing, so that no instruction comes from flash while the erase runs.
///
/// # Safety
/// Interrupts must be off (their vectors and handlers are in flash) and the flash
/// unlocked.
#[unsafe(link_section = ".data.erase_in_ram")]
#[inline(never)]
unsafe extern "C" fn erase_in_ram(snb: u32) -> u32 {
    // SAFETY: fixed register addresses of the F405's flash controller and IWDG.
    unsafe {
        let cr = CR_PSIZE_X32 | CR_SER | (snb << 3);
        write_volatile(CR, cr);
        write_volatile(CR, cr | CR_STRT);
        while read_volatile(SR) & SR_BSY != 0 {
            write_volatile(IWDG_KR, 0xAAAA);
        }
        let status = read_volatile(SR);
        write_volatile(CR, 0);
        status
    }
}

fn unlock() {
    // SAFETY: the documented key sequence; a wrong one would lock the controller
    // until reset, never write anything.
    unsafe {
        if read_volatile(CR) & CR_LOCK != 0 {
            write_volatile(KEYR, 0x4567_0123);
            write_volatile(KEYR, 0xCDEF_89AB);
        }
        // Clear the error flags of an earlier operation (write 1 to clear).
        write_volatile(SR, SR_ERRORS | 1);
    }
}

fn lock() {
    // SAFETY: setting LOCK only forbids further writes until the next unlock.
    unsafe { write_volatile(CR, CR_LOCK) }
}

/// The data cache may hold what a region address read before the erase or the
/// program: reset it so that reads see flash.
fn flush_data_cache() {
    // SAFETY: the ART data cache reset sequence (cache off, reset, on).
    unsafe {
        let acr = read_volatile(ACR);
        write_volatile(ACR, acr & !ACR_DCEN);
        write_volatile(ACR, (acr & !ACR_DCEN) | ACR_DCRST);
        write_volatile(ACR, acr & !ACR_DCEN);
        write_volatile(ACR, acr);
    }
}

impl Flash for BankFlash {
    fn erase(&mut self, sector: usize) -> Result<(), FlashError> {
        if sector >= REGION_LEN / SECTOR_LEN {
            return Err(FlashError::Failed);
        }
        unlock();
        let status = cortex_m::interrupt::free(|_| {
            // SAFETY: interrupts are off, the flash is unlocked.
            unsafe { erase_in_ram(FIRST_SECTOR + sector as u32) }
        });
        lock();
        flush_data_cache();
        if status & SR_ERRORS != 0 {
            return Err(FlashError::Failed);
        }
        Ok(())
    }

    fn program(&mut self, offset: usize, word: u32) -> Result<(), FlashError> {
        if !offset.is_multiple_of(4) || offset + 4 > REGION_LEN {
            return Err(FlashError::NotErased);
        }
        let addr = (REGION_ADDR + offset) as *mut u32;
        // SAFETY: an aligned address inside the bank region.
        if unsafe { read_volatile(addr) } != 0xFFFF_FFFF {
            return Err(FlashError::NotErased);
        }
        unlock();
        // SAFETY: the program sequence of RM0090 3.6.4 at x32 on an erased word.
        let status = unsafe {
            write_volatile(CR, CR_PSIZE_X32 | CR_PG);
            write_volatile(addr, word);
            while read_volatile(SR) & SR_BSY != 0 {}
            read_volatile(SR)
        };
        lock();
        flush_data_cache();
        // SAFETY: as above.
        if status & SR_ERRORS != 0 || unsafe { read_volatile(addr) } != word {
            return Err(FlashError::Failed);
        }
        Ok(())
    }

    fn region(&self) -> &[u8] {
        super::bank_region()
    }
}
