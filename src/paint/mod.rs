//! `ipfn synth` as a library request: [`SynthRequest`] holds every flag, checks them against
//! the model once and returns a [`SynthPlan`], which paints a generator's image, map set, slice
//! or volume, or a fitted tile, into files or into memory. The command line and the Python
//! package only fill the request.

mod plan;
mod request;

pub use plan::{Painted, SynthPlan};
pub use request::{DEFAULT_SIZE, Size, SynthRequest, ZarrOptions};
