//! `ipfn`: the Implicit Periodic Field Network (Chen et al., "Exemplar-based Pattern Synthesis
//! with Implicit Periodic Field Network", CVPR 2022) in Rust.
//!
//! Modules follow the method (the book's design page "How the code is laid out" shows how data
//! flows):
//! - [`encoding`]: the periodic sin/cos encoding of `p / K`.
//! - [`latent`]: the infinite, deterministic latent random field (CPU, and its device lattice).
//! - [`sample`]: coordinate grids of pixels, for synthesis and for training crops.
//! - [`condition`]: the generator's optional condition: guidance (images) or density (volumes).
//! - [`generator`]: the MLP generator (burn module, fused CPU evaluator, GPU kernel, PyTorch import).
//! - [`critic`]: the critic over 2 or 3 axes, with its exact input gradient for the penalty.
//! - [`train`]: WGAN-GP training: config, data, fakes, step, run folder and loop, Adam.
//! - [`synth`]: painting regions, images, map sets and volumes, tileable or not.
//! - [`model`]: which model a command paints with (most recent, shipped).
//! - [`paint`]: `ipfn synth` as a request: every flag checked once, painted into files or memory.
//! - [`device`]: device choice and probes (cpu, flex, wgpu, cuda).
//! - [`exemplar`]: exemplar images and SDF volumes, read into [-1, 1].
//! - [`checkpoint`]: model files (`.ipfn`, safetensors).
//! - [`io`]: arrays, images and volumes out, written atomically; the run folder's lock.
//! - [`maps`]: material map sets (albedo, normal, height, ...) learned and painted together.
//! - [`mesh`]: zero level sets of volumes as meshes (surface nets), welded across chunks.
//! - [`metrics`]: SIFID (Keras InceptionV3 stem), structure distance (autocorrelation), seam
//!   score of tiles, dominant periods.
//! - [`eval`]: `ipfn eval`: a model against its exemplar, or two images.
//! - [`fit`]: `ipfn fit`, a photo turned into a seamless tile by a periodic sine network.
//! - [`procedural`]: exemplars drawn by our own code, with known periods.
//! - [`report`]: a run folder read back as data, for `ipfn view` and `report.html`.
//! - [`view`]: `ipfn view`, the plane and the run in a browser.
//! - [`bench`]: `ipfn bench`, speed beside floors measured in the same run.
//! - [`cli`]: the `ipfn` command line.

pub mod bench;
pub mod checkpoint;
#[cfg(feature = "cli")]
pub mod cli;
pub mod condition;
pub mod critic;
pub mod device;
#[cfg(test)]
mod docs_tests;
pub mod draw;
pub mod encoding;
pub mod error;
pub mod eval;
pub mod exemplar;
pub mod fit;
pub mod generator;
pub mod io;
pub mod latent;
#[cfg(test)]
mod layout_tests;
pub mod maps;
pub mod mesh;
pub mod metrics;
pub mod model;
pub mod paint;
pub mod procedural;
pub mod report;
pub mod sample;
pub mod stop;
pub mod synth;
#[cfg(test)]
pub(crate) mod testing;
pub mod train;
#[cfg(feature = "view")]
pub mod view;

pub use error::{Error, Result};
