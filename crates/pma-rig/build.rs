//! Links libcomedi when the `comedi` feature is on (Cargo sets `CARGO_FEATURE_COMEDI` for
//! the build script then, and compiles it with `feature = "comedi"`, which also brings the
//! optional `pkg-config` build dependency). Without the feature there is nothing to link.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    #[cfg(feature = "comedi")]
    link_comedilib();
}

/// Finds comedilib with pkg-config, which prints the `cargo:rustc-link-*` lines itself.
/// `cargo::error` fails the build with just that message, without the script's other output.
#[cfg(feature = "comedi")]
fn link_comedilib() {
    // 0.8 is the first comedilib with `comedi_get_hardcal_converter`, which ffi.rs declares.
    if let Err(error) = pkg_config::Config::new()
        .atleast_version("0.8")
        .probe("comedilib")
    {
        println!(
            "cargo::error=the `comedi` feature needs comedilib (>= 0.8), which pkg-config \
             cannot find: install it with `sudo apt install libcomedi-dev pkg-config`"
        );
        // pkg-config's own explanation, for an unusual installation (one line per message).
        for line in error
            .to_string()
            .lines()
            .filter(|line| !line.trim().is_empty())
        {
            println!("cargo::warning=pkg-config: {}", line.trim());
        }
    }
}
