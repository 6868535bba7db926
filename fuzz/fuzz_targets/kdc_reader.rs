//! .kdc compiled scenes: the input is decoded twice, as is (the checksum almost always fails)
//! and resealed with a correct checksum so that the header and section validation behind it is
//! reached. Whatever is accepted is rendered (4x4 pixels, 1 spp) on the CPU: a validated file
//! must never make the renderer panic or index out of bounds.
#![no_main]
use kdtrace::render::{cpu, kdc};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.kdc");
    let _ = kdc::decode(path, data);
    let mut sealed = data.to_vec();
    kdc::seal(&mut sealed);
    if let Ok(k) = kdc::decode(path, &sealed) {
        let c = &k.compiled;
        let mut s = k.settings.clone();
        s.width = Some(4);
        s.height = Some(4);
        s.spp = Some(1);
        s.bounces = Some(s.bounces.unwrap_or(1).min(3));
        let (lo, hi) = c.world_bounds();
        if let Ok(rs) = s.resolve(lo, hi) {
            cpu::render(c, &rs, &|_, _| {}).expect("a validated scene renders");
        }
    }
});
