#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    morphoid_fuzz::pp(data);
});
