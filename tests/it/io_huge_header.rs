//! A PLY header claiming four billion vertices fails at once, without
//! allocating for them. Its own test binary, so that the allocation
//! counter sees nothing else.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let now = CURRENT.fetch_add(layout.size(), Ordering::SeqCst) + layout.size();
        PEAK.fetch_max(now, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

#[test]
fn four_billion_vertices_fail_without_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let files = morphoid_synth::mesh::write_bad_inputs(dir.path()).unwrap();
    let (path, _) = files
        .iter()
        .find(|(p, _)| p.ends_with("four_billion.ply"))
        .unwrap();
    let before = CURRENT.load(Ordering::SeqCst);
    PEAK.store(before, Ordering::SeqCst);
    let err = morphoid_data::mesh_io::load(path).unwrap_err().to_string();
    let peak = PEAK.load(Ordering::SeqCst) - before;
    println!("{err}\npeak extra memory: {peak} bytes");
    assert!(
        err.contains("four_billion.ply") && err.contains("4000000000"),
        "{err}"
    );
    assert!(peak < 1 << 20, "peak {peak} bytes");
}
