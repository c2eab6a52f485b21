//! ipfn's integration tests, one binary: the command line run on real files, the library's
//! requests end to end, and the backends against each other. One binary links the library
//! once; the two that need a process of their own (the mutation harness's allocator, the
//! kernel's device-memory report) stay beside it in tests/.

#[macro_use]
mod common;

mod cli;
mod fit;
mod guidance;
mod kernel;
mod maps;
mod metrics;
mod recipe;
mod reference;
mod solid;
mod stops;
mod synth;
mod train;
mod view;
mod view_browser;
mod volume;
mod volume_train;
mod voxelize;
mod zarr;
