//! A global allocator that counts the allocations (and reallocations) made on each thread,
//! for the tests that check that per-frame work allocates nothing, and the bytes each
//! thread holds (live and peak), for the tests that bound a reader's memory. Include it with
//! `#[path = "common/counting_alloc.rs"] mod counting_alloc;` (a test crate has one global
//! allocator, so it is not part of `common`).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
    /// Bytes allocated minus bytes freed on this thread (memory freed on another thread
    /// than the one that allocated it makes this drift, hence signed).
    static LIVE_BYTES: Cell<isize> = const { Cell::new(0) };
    /// The largest `LIVE_BYTES` since the last [`reset_peak`].
    static PEAK_BYTES: Cell<isize> = const { Cell::new(0) };
    /// Single requests above this many bytes are reported on stderr with [`LABEL`] before
    /// they are attempted (an impossible one aborts the process, leaving no other trace).
    static REPORT_ABOVE: Cell<usize> = const { Cell::new(usize::MAX) };
    /// What this thread is doing, for that report (see [`report_requests_above`]).
    static LABEL: Cell<[u8; 200]> = const { Cell::new([0; 200]) };
}

/// Writes a note naming the thread's label when a request is over the reporting threshold;
/// writes straight to stderr, which allocates nothing.
fn report_if_large(size: usize) {
    if size > REPORT_ABOVE.with(Cell::get) {
        use std::io::Write;
        let label = LABEL.with(Cell::get);
        let end = label.iter().position(|&b| b == 0).unwrap_or(label.len());
        let mut err = std::io::stderr();
        let _ = err.write_all(b"\nallocation request above the reporting threshold while: ");
        let _ = err.write_all(&label[..end]);
        let _ = err.write_all(b"\n");
    }
}

/// From now on, this thread reports single allocation requests above `bytes` on stderr,
/// naming `label` (truncated to 199 bytes): the trace left when a reader asks for
/// impossible memory and the process aborts.
#[allow(dead_code)]
pub fn report_requests_above(bytes: usize, label: &str) {
    let mut buffer = [0u8; 200];
    let n = label.len().min(199);
    buffer[..n].copy_from_slice(&label.as_bytes()[..n]);
    LABEL.with(|l| l.set(buffer));
    REPORT_ABOVE.with(|r| r.set(bytes));
}

fn add_live(delta: isize) {
    let live = LIVE_BYTES.with(|c| {
        let v = c.get().wrapping_add(delta);
        c.set(v);
        v
    });
    PEAK_BYTES.with(|p| p.set(p.get().max(live)));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        add_live(layout.size() as isize);
        report_if_large(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        add_live(layout.size() as isize);
        report_if_large(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        add_live(-(layout.size() as isize));
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        add_live(new_size as isize - layout.size() as isize);
        report_if_large(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made on this thread so far.
pub fn allocations() -> usize {
    ALLOCATIONS.with(|c| c.get())
}

/// Allocations made on this thread while `f` runs.
#[allow(dead_code)]
pub fn allocations_during(f: impl FnOnce()) -> usize {
    let before = allocations();
    f();
    allocations() - before
}

/// The most bytes this thread held at once while `f` ran, above what it held before, and
/// `f`'s result.
#[allow(dead_code)]
pub fn peak_bytes_during<R>(f: impl FnOnce() -> R) -> (usize, R) {
    let before = LIVE_BYTES.with(Cell::get);
    PEAK_BYTES.with(|p| p.set(before));
    let r = f();
    let peak = PEAK_BYTES.with(Cell::get);
    (peak.saturating_sub(before).max(0) as usize, r)
}
