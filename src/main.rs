//! The `gloam` binary: everything happens in `gloam::cli`.

fn main() -> std::process::ExitCode {
    gloam::cli::main()
}
