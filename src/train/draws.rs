//! Every random draw of training is a hash of `(seed, purpose, counters)`, so a resumed run
//! continues bit for bit: the purposes ([`stream`]), uniform draws ([`uniform`]) and the
//! networks' initial weights ([`initialise`]).

use burn::module::{Module, ParamId};
use burn::prelude::*;

use crate::checkpoint::{MapByPath, map_by_path};
use crate::latent::mix64;

/// Purposes of random draws, so no two share a stream.
pub mod stream {
    // The coarse critic's (see `coarse`) draw from streams of their own, so a run without it
    // draws exactly as before.
    pub const INIT_GENERATOR: u64 = 1;
    pub const INIT_CRITIC: u64 = 2;
    pub const REAL_CROP: u64 = 3;
    pub const SHIFT: u64 = 4;
    pub const LATENT: u64 = 5;
    pub const ALPHA: u64 = 6;
    pub const CRITIC_FAKE: u64 = 7;
    pub const GENERATOR_FAKE: u64 = 8;
    pub const PREVIEW: u64 = 9;
    pub const GUIDE: u64 = 10;
    pub const SLICE_AXIS: u64 = 11;
    pub const DIVERSITY: u64 = 12;
    pub const COARSE_REAL_CROP: u64 = 13;
    pub const COARSE_CRITIC_FAKE: u64 = 14;
    pub const COARSE_GENERATOR_FAKE: u64 = 15;
    pub const COARSE_ALPHA: u64 = 16;
    pub const INIT_COARSE_CRITIC: u64 = 17;
}

pub(crate) use crate::latent::unit_uniform as uniform;

/// Re-initialises every float parameter except the generator's K with PyTorch's default
/// uniform(-1/sqrt(fan_in), 1/sqrt(fan_in)), from hashed draws.
pub(crate) fn initialise<M: Module>(module: M, seed: u64, stream: u64) -> M {
    struct Init {
        seed: u64,
        stream: u64,
        fan_in: usize,
    }
    impl MapByPath for Init {
        fn map<const D: usize>(&mut self, path: &str, _: ParamId, tensor: Tensor<D>) -> Tensor<D> {
            let name = path.rsplit('.').next().unwrap_or_default();
            if name == "k" {
                return tensor;
            }
            let shape = tensor.dims();
            if name == "weight" {
                // Linear weights are [in, out]; convolution weights [out, in, kh, kw].
                self.fan_in = if D == 2 {
                    shape[0]
                } else {
                    shape[1..].iter().product()
                };
            }
            let bound = 1.0 / (self.fan_in.max(1) as f32).sqrt();
            let key = path.split('.').fold(self.seed, |h, p| {
                mix64(h ^ p.bytes().fold(0u64, |a, b| mix64(a ^ b as u64)))
            });
            let n: usize = shape.iter().product();
            let values: Vec<f32> = (0..n as u64)
                .map(|i| (uniform(key, &[self.stream, i]) * 2.0 - 1.0) * bound)
                .collect();
            Tensor::<D>::from_data(TensorData::new(values, shape), &tensor.device())
        }
    }
    let mut init = Init {
        seed,
        stream,
        fan_in: 1,
    };
    map_by_path(module, &mut init)
}
