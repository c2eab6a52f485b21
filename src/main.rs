//! The `ipfn` binary: everything lives in the library; see `ipfn --help`.

#[cfg(feature = "cuda")]
mod llvm_stubs;

fn main() {
    if let Err(error) = ipfn::cli::run() {
        eprintln!("error: {error}");
        std::process::exit(error.exit_code());
    }
}
