//! The built binary and the files it writes: running `ohd` and reading a PNG's size.

use std::path::Path;
use std::process::{Command, Output, Stdio};

/// Run `ohd args…` in `cwd` with every standard stream piped (not a terminal).
pub fn ohd(cwd: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ohd"))
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .output()
        .expect("ohd starts")
}

/// Width and height of a PNG file (and that it decodes).
pub fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().expect("PNG header");
    let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    (info.width, info.height)
}
