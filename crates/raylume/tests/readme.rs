//! The README's "Use it as a library" code is `readme/quickstart.rs`, word for word, and it
//! compiles (as part of this test) and runs.

mod quickstart {
    include!("readme/quickstart.rs");

    pub fn run() -> Result<(), Box<dyn std::error::Error>> {
        main()
    }
}

const README: &str = include_str!("../../../README.md");
const SNIPPET: &str = include_str!("readme/quickstart.rs");

/// The first ```rust block after `heading` in the README.
fn block_after(heading: &str) -> &'static str {
    let start = README
        .find(heading)
        .unwrap_or_else(|| panic!("README has no `{heading}`"));
    let rest = &README[start..];
    let open = rest.find("```rust\n").expect("a ```rust block") + "```rust\n".len();
    let len = rest[open..].find("```\n").expect("the block's end");
    &rest[open..open + len]
}

#[test]
fn readme_library_code_is_the_tested_file() {
    assert_eq!(
        block_after("## Use it as a library"),
        SNIPPET,
        "README.md and crates/raylume/tests/readme/quickstart.rs differ: copy one to the other"
    );
}

#[test]
fn readme_library_code_runs() {
    quickstart::run().unwrap();
    let _ = std::fs::remove_file(std::env::temp_dir().join("raylume-quickstart.png"));
}

#[test]
fn readme_cargo_line_names_the_facade_by_path() {
    let section = &README[README.find("## Use it as a library").unwrap()..];
    assert!(
        section.contains("raylume = { path = \"") && section.contains("/crates/raylume\" }"),
        "the Cargo.toml line"
    );
}
