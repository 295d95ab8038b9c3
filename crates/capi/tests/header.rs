//! The checked-in C header `include/piezohyst.h` is what cbindgen generates from the
//! current source; `PIEZOHYST_BLESS=1` rewrites it instead of failing.
use std::path::PathBuf;

#[test]
fn header_is_up_to_date() {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(&crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen failed")
        .write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    let path = crate_dir.join("include/piezohyst.h");
    if std::env::var_os("PIEZOHYST_BLESS").is_some() {
        std::fs::write(&path, &generated).unwrap();
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "{} is stale: regenerate it with `PIEZOHYST_BLESS=1 cargo test -p piezohyst-capi --test header` and commit it",
        path.display()
    );
}
