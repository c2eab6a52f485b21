//! `ipfn`: the Implicit Periodic Field Network (Chen et al., "Exemplar-based Pattern Synthesis
//! with Implicit Periodic Field Network", CVPR 2022) in Rust.
//!
//! Modules follow the method:
//! - [`encoding`]: the periodic sin/cos encoding of `p / K`.
//! - [`latent`]: the infinite, deterministic latent random field.
//! - [`generator`]: the MLP generator (a burn module, and a fused CPU evaluator).
//! - [`guidance`]: directional guidance (conditional IPFN): a guidance channel `g`.
//! - [`critic`]: the critic, with its exact input gradient for the gradient penalty.
//! - [`train`]: WGAN-GP training, checkpoints and resume.
//! - [`sample`]: coordinate grids of pixels.
//! - [`procedural`]: exemplars drawn by our own code, with known periods.
//! - [`synth`]: painting regions and whole images, tileable or not.
//! - [`checkpoint`]: model files, and import of the authors' PyTorch generators.
//! - [`io`]: arrays and images in and out, written atomically.
//! - [`maps`]: material map sets (albedo, normal, height, ...) learned and painted together.
//! - [`mesh`]: zero level sets of volumes as meshes (surface nets), welded across chunks.
//! - [`metrics`]: SIFID (Keras InceptionV3 stem), seam score of tiles, dominant periods.
//! - [`bench`]: `ipfn bench`, speed beside floors measured in the same run.
//! - [`cli`]: the `ipfn` command line.

pub mod bench;
pub mod checkpoint;
pub mod cli;
pub mod critic;
pub mod encoding;
pub mod error;
pub mod generator;
pub mod guidance;
pub mod io;
pub mod latent;
pub mod maps;
pub mod mesh;
pub mod metrics;
pub mod procedural;
pub mod sample;
pub mod synth;
pub mod train;

pub use error::{Error, Result};
