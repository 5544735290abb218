//! Link arguments for the firmware image only; the no_std core library builds for any target.
fn main() {
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumb") {
        let out = std::path::PathBuf::from(std::env::var("OUT_DIR").unwrap());
        std::fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
        println!("cargo:rustc-link-search={}", out.display());
        // Only the firmware binary links with cortex-m-rt's and defmt's scripts.
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
        // The on-target test suite (tests/on_target.rs, embedded-test): the same scripts and
        // embedded-test's table of test cases.
        println!("cargo:rustc-link-arg-tests=--nmagic");
        println!("cargo:rustc-link-arg-tests=-Tlink.x");
        println!("cargo:rustc-link-arg-tests=-Tdefmt.x");
        println!("cargo:rustc-link-arg-tests=-Tembedded-test.x");
    }
    // embedded-test's macro emits `cfg(rust_analyzer)`.
    println!("cargo:rustc-check-cfg=cfg(rust_analyzer)");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
