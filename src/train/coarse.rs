//! The coarse critic: a second critic that judges the pattern's arrangement.
//!
//! The fine critic's crops are a few dozen pixels wide, often less than one cell of a regular
//! pattern: no crop holds two cells, so the arrangement of the cells (hexagons, offset rows of
//! bricks) cannot be learned from it, and the generator falls back to a lattice the size of a
//! crop. The generator is a function of coordinates, so a crop `stride` times wider can be
//! painted on a strided grid of `crop x crop` points, at the cost of one fine crop; the
//! exemplar is read at the same stride (every `stride`-th pixel, unfiltered, so that real and
//! generated crops alias alike). A coarse critic of the same architecture judges those; the
//! generator's loss adds both critics' scores, so the fine critic keeps the detail and the
//! coarse one the layout. A stride that makes the coarse crop span two to four of the pattern's
//! periods is the intent. It is off by default (`coarse_stride = 0`): at equal time it has not
//! beaten a working scale at which the fine crop holds one whole period
//! ([`super::recipe::cell_scale`]). Where the rows alternate, the recipe turns it on with K
//! held on two courses ([`super::recipe::alternating_rows`]): only that pair paints a running
//! bond.

use super::Trainer;
use super::adam::Adam;
use super::draws::stream;
use crate::critic::Critic;

/// Which of the two critics' grids a crop is drawn on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// Every pixel of a `crop`-pixel crop: the paper's critic.
    Fine,
    /// Every `coarse_stride`-th pixel of a crop `coarse_stride` times wider.
    Coarse,
}

impl Scale {
    /// The random stream of the real crops' origins.
    pub(super) fn real_crop_stream(self) -> u64 {
        match self {
            Scale::Fine => stream::REAL_CROP,
            Scale::Coarse => stream::COARSE_REAL_CROP,
        }
    }

    /// The random stream of the generated crops the critic steps score.
    pub(super) fn critic_fake_stream(self) -> u64 {
        match self {
            Scale::Fine => stream::CRITIC_FAKE,
            Scale::Coarse => stream::COARSE_CRITIC_FAKE,
        }
    }

    /// The random stream of the generated crops the generator steps score.
    pub(super) fn generator_fake_stream(self) -> u64 {
        match self {
            Scale::Fine => stream::GENERATOR_FAKE,
            Scale::Coarse => stream::COARSE_GENERATOR_FAKE,
        }
    }

    /// The random stream of the penalty's interpolation weights.
    pub(super) fn alpha_stream(self) -> u64 {
        match self {
            Scale::Fine => stream::ALPHA,
            Scale::Coarse => stream::COARSE_ALPHA,
        }
    }
}

/// Whether a run with `config` trains a second, coarse critic: a coarse stride without a
/// coarse-to-fine schedule (with one, the one critic judges both in turn).
pub(super) fn has_coarse_critic(config: &super::TrainConfig) -> bool {
    config.coarse_stride > 0 && config.coarse_until == 0.0
}

/// The coarse critic and its optimiser, as a run keeps them.
pub(super) struct CoarseCritic {
    pub critic: Critic,
    pub adam: Adam,
}

/// The largest stride whose coarse crop of `crop` points fits in `side` pixels.
pub fn largest_stride(side: usize, crop: usize) -> usize {
    if crop < 2 {
        return 1;
    }
    (side.saturating_sub(1) / (crop - 1)).max(1)
}

impl Trainer {
    /// Pixels between two points of a crop at `scale`.
    pub(super) fn stride(&self, scale: Scale) -> usize {
        match scale {
            Scale::Fine if self.in_coarse_phase() => self.config.coarse_stride,
            Scale::Fine => 1,
            Scale::Coarse => self.config.coarse_stride.max(1),
        }
    }

    /// Whether the iteration about to run is in the coarse part of a coarse-to-fine schedule
    /// (`coarse_until`), where the one critic judges strided crops. A time budget's plan
    /// moves the switch with the planned total.
    pub(super) fn in_coarse_phase(&self) -> bool {
        self.config.coarse_until > 0.0
            && (self.iteration as f64) < self.config.coarse_until * self.config.iterations as f64
    }

    /// The scales whose critics this run trains: the fine one, and the coarse one when
    /// `coarse_stride` is set.
    pub(super) fn scales(&self) -> &'static [Scale] {
        if self.coarse.is_some() {
            &[Scale::Fine, Scale::Coarse]
        } else {
            &[Scale::Fine]
        }
    }

    /// The coarse critic, where the run has one.
    pub fn coarse_critic(&self) -> Option<&Critic> {
        self.coarse.as_ref().map(|c| &c.critic)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_stride_fits_the_exemplar() {
        // 427 px hold a crop of 32 points every 13 px: (32 - 1) · 13 + 1 = 404.
        assert_eq!(largest_stride(427, 32), 13);
        assert_eq!(largest_stride(404, 32), 13);
        assert_eq!(largest_stride(403, 32), 12);
        assert_eq!(largest_stride(20, 32), 1);
    }

    #[test]
    fn a_strided_crop_is_the_wide_crops_every_nth_pixel() {
        use crate::sample::{crop_coordinate, strided_crop_coordinate};
        // Point i of the strided crop sits where pixel i · stride of a crop `stride` times
        // wider (spanning 2 · stride units) has its centre.
        let (crop, stride) = (32, 4);
        for i in [0, 1, 17, 31] {
            let wide =
                -(stride as f32) + (i * stride) as f32 * 2.0 / crop as f32 + 1.0 / crop as f32;
            assert!((strided_crop_coordinate(crop, stride, i, 0.25) - (wide + 0.25)).abs() < 1e-6);
            assert_eq!(
                strided_crop_coordinate(crop, 1, i, 0.25),
                crop_coordinate(crop, i, 0.25)
            );
        }
    }
}
