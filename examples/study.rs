//! The error-versus-time study (issue 20, item 5): placeholder, being written.
fn main() {}
