//! The slot documentation of `PhsFamily` and `PhsControllerKind` in `src/lib.rs` (and so in
//! the cbindgen header `include/piezohyst.h`) is generated from the core's layout table
//! (`piezohyst_core::layout`): this test renders the table and fails when the doc blocks
//! between the `<!-- layout:... -->` markers, or the enum codes, disagree with it.
//! `PIEZOHYST_BLESS=1` rewrites the blocks in `src/lib.rs` (then run `tests/header.rs`
//! with it too, to regenerate the header).
use std::path::PathBuf;

use piezohyst_core::layout::{controller_doc, family_doc, CONTROLLERS, FAMILIES};

/// The lines a doc renderer of the core writes.
fn rendered(render: impl FnOnce(&mut dyn FnMut(std::fmt::Arguments<'_>))) -> Vec<String> {
    let mut lines = Vec::new();
    render(&mut |a| lines.push(format!("{a}")));
    lines
}

fn families() -> Vec<String> {
    rendered(|line| family_doc(line))
}
fn controllers() -> Vec<String> {
    rendered(|line| controller_doc(line))
}

/// `text` with the lines between `<!-- {tag} -->` and `<!-- /{tag} -->` (doc comments)
/// replaced by `lines`.
fn splice(text: &str, tag: &str, lines: &[String]) -> String {
    let open = format!("/// <!-- {tag} -->\n");
    let close = format!("/// <!-- /{tag} -->\n");
    let a = text.find(&open).unwrap_or_else(|| panic!("marker {open:?} missing")) + open.len();
    let b = a + text[a..].find(&close).unwrap_or_else(|| panic!("marker {close:?} missing"));
    let mut body = String::new();
    for l in lines {
        body.push_str(format!("/// {l}").trim_end());
        body.push('\n');
    }
    format!("{}{}{}", &text[..a], body, &text[b..])
}

#[test]
fn lib_doc_blocks_come_from_the_layout_table() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs");
    let source = std::fs::read_to_string(&path).unwrap();
    let fresh = splice(&splice(&source, "layout:families", &families()), "layout:controllers", &controllers());
    if std::env::var_os("PIEZOHYST_BLESS").is_some() {
        if fresh != source {
            std::fs::write(&path, &fresh).unwrap();
        }
        return;
    }
    assert!(
        fresh == source,
        "the layout doc blocks of {} are stale: regenerate with `PIEZOHYST_BLESS=1 cargo test -p piezohyst-capi --test \
         layout_doc --test header` and commit",
        path.display()
    );
}

#[test]
fn header_names_every_table_row_with_its_code_and_slots() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("include/piezohyst.h");
    let header = std::fs::read_to_string(path).unwrap();
    for f in FAMILIES {
        assert!(header.contains(&format!("PHS_FAMILY_{} = {},", f.label, f.code)), "PHS_FAMILY_{}", f.label);
    }
    for c in CONTROLLERS {
        assert!(header.contains(&format!("PHS_CONTROLLER_{} = {},", c.label, c.code)), "PHS_CONTROLLER_{}", c.label);
    }
    for l in families().iter().chain(&controllers()) {
        assert!(header.contains(l.trim_end()), "the header lacks the table line {l:?}");
    }
}
