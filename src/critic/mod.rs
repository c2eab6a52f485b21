//! The critic D (DCGAN-style, no normalisation) and its exact input gradient, over 2 or 3 axes.
//!
//! D = head ∘ flatten ∘ (leaky ∘ conv_4) ∘ ... ∘ (leaky ∘ conv_1), each convolution kernel 4,
//! stride 2, padding 1 on every axis, LeakyReLU slope 0.01, then one linear layer to a score.
//! Images (and a solid texture's slices) use 2D convolutions, volumes 3D ones (paper §4.2); the
//! difference is made in one place, [`Critic::conv`] and [`Critic::conv_transpose`]. Every
//! batch is `[batch, channels, depth, rows, cols]`, with `depth = 1` for images.
//!
//! WGAN-GP needs `||dD/dx||` and its gradient with respect to D's weights. burn has no
//! second-order autodiff, but D is piecewise linear, so
//! `dD/dx = W_1^T M_1 W_2^T M_2 ... W_4^T M_4 w_head`, where `M_l` is the (detached) LeakyReLU
//! slope mask of layer l and `W_l^T` is a transposed convolution with the same weights.
//! [`Critic::input_gradient`] builds that product from ordinary tensor ops, so first-order
//! autodiff differentiates the penalty with respect to the weights exactly. On the CPU,
//! [`fused`] computes the same loss and gradients by hand.

use burn::module::Param;
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::Distribution;
use burn::tensor::activation::leaky_relu;
use burn::tensor::module::{conv_transpose2d, conv_transpose3d, conv2d, conv3d};
use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};

use crate::input_error;

pub mod fused;
mod geometry;
#[cfg(test)]
mod tests;

/// Kernel side of every convolution.
const KERNEL: usize = 4;

/// Shape of a critic. The crop must be a multiple of 2^(number of convolutions).
#[derive(Config, Debug, PartialEq)]
pub struct CriticConfig {
    /// Input channels (the exemplar's, plus one for a condition).
    pub channels: usize,
    /// Input side in pixels (or voxels) on every axis.
    pub crop: usize,
    /// Spatial axes: 2 for images and a solid texture's slices, 3 for volumes.
    #[config(default = 2)]
    pub axes: usize,
    /// Output channels of each stride-2 convolution.
    #[config(default = "vec![64, 128, 256, 512]")]
    pub widths: Vec<usize>,
    /// Negative slope of the LeakyReLU (the authors' code uses PyTorch's default, 0.01).
    #[config(default = 0.01)]
    pub slope: f64,
}

/// The most parameters a critic may have: 2^26 (the paper's has 2.8M).
pub const MAX_CRITIC_PARAMETERS: usize = 1 << 26;

impl CriticConfig {
    /// Side of the last feature map.
    pub fn final_side(&self) -> usize {
        self.crop >> self.widths.len()
    }

    pub fn validate(&self) -> crate::Result<()> {
        if !(2..=3).contains(&self.axes) {
            return Err(input_error!(
                "the critic has 2 or 3 axes, not {}",
                self.axes
            ));
        }
        if self.widths.is_empty()
            || self.widths.len() > 8
            || self.widths.iter().any(|&w| w == 0 || w > 4096)
        {
            return Err(crate::setting_error!(
                "critic_widths",
                format!("{:?}", self.widths),
                "1 to 8 layers of 1 to 4096 channels"
            ));
        }
        // Weights: 4^axes taps per input and output channel pair.
        let taps = 4usize.pow(self.axes as u32);
        let parameters: usize = std::iter::once(self.channels)
            .chain(self.widths.iter().copied())
            .collect::<Vec<_>>()
            .windows(2)
            .map(|w| w[0] * w[1] * taps)
            .sum();
        if parameters > MAX_CRITIC_PARAMETERS {
            return Err(crate::setting_error!(
                "critic_widths",
                format!("{:?}", self.widths),
                "{parameters} critic parameters, at most {MAX_CRITIC_PARAMETERS}"
            ));
        }
        let factor = 1usize << self.widths.len();
        if self.crop == 0 || !self.crop.is_multiple_of(factor) {
            return Err(input_error!(
                "crop {}: the critic halves the crop {} times, so it must be a positive multiple of {factor} (e.g. --crop {})",
                self.crop,
                self.widths.len(),
                (self.crop.max(factor) / factor) * factor
            ));
        }
        Ok(())
    }

    /// A critic with PyTorch-style uniform initialisation on `device`.
    pub fn init(&self, device: &Device) -> Critic {
        let depth = if self.axes == 3 { KERNEL } else { 1 };
        let mut inputs = self.channels;
        let convs = self
            .widths
            .iter()
            .map(|&w| {
                let fan_in = inputs * depth * KERNEL * KERNEL;
                let bound = 1.0 / (fan_in as f64).sqrt();
                let uniform = Distribution::Uniform(-bound, bound);
                let conv = Conv {
                    weight: Param::from_tensor(Tensor::random(
                        [w, inputs, depth, KERNEL, KERNEL],
                        uniform,
                        device,
                    )),
                    bias: Some(Param::from_tensor(Tensor::random([w], uniform, device))),
                };
                inputs = w;
                conv
            })
            .collect();
        let features = inputs * self.final_side().pow(self.axes as u32);
        Critic {
            convs,
            head: LinearConfig::new(features, 1).init(device),
            slope: self.slope,
            axes: self.axes,
        }
    }
}

/// One stride-2 convolution. The weight is `[out, in, depth, kernel, kernel]`, with `depth = 1`
/// for a 2D critic (files written before the critic was one type store it without that axis;
/// [`crate::checkpoint::Checkpoint::tensor`] reads either). [`Critic::weights`] gives the shape
/// the convolution takes.
#[derive(Module, Debug)]
pub struct Conv {
    pub weight: Param<Tensor<5>>,
    pub bias: Option<Param<Tensor<1>>>,
}

/// The critic as a burn module.
#[derive(Module, Debug)]
pub struct Critic {
    pub convs: Vec<Conv>,
    pub head: Linear,
    pub slope: f64,
    /// Spatial axes: 2 or 3.
    pub axes: usize,
}

/// The critic's convolution weights as its convolutions take them: `[out, in, k, k]` in 2D,
/// `[out, in, k, k, k]` in 3D. Made once per evaluation ([`Critic::weights`]) and shared by every
/// use in it (the scores of real and fake crops and the penalty's transposes), so each weight
/// reaches autodiff through one reshape and its gradient sums its uses in the same order as a
/// plain 2D critic's: training stays bit for bit what it was before the critic was one type.
pub enum Weights {
    Planar(Vec<Tensor<4>>),
    Volumetric(Vec<Tensor<5>>),
}

impl Critic {
    /// The convolution weights for one evaluation (see [`Weights`]).
    pub fn weights(&self) -> Weights {
        let all = self.convs.iter().map(|c| c.weight.val());
        if self.axes == 3 {
            return Weights::Volumetric(all.collect());
        }
        Weights::Planar(
            all.map(|w| {
                let [o, i, _, k, _] = w.dims();
                w.reshape([o, i, k, k])
            })
            .collect(),
        )
    }

    /// The one place where 2 and 3 axes differ: stride-2 convolution `layer`.
    ///
    /// # Shapes
    /// - `x`: `[batch, in, depth, rows, cols]` (depth 1 in 2D)
    /// - output: `[batch, out, depth / 2, rows / 2, cols / 2]` (depth 1 in 2D)
    fn conv(&self, weights: &Weights, layer: usize, x: Tensor<5>) -> Tensor<5> {
        let bias = self.convs[layer].bias.as_ref().map(|b| b.val());
        let w = match weights {
            Weights::Volumetric(w) => {
                let options = ConvOptions::new([2; 3], [1; 3], [1; 3], 1);
                return conv3d(x, w[layer].clone(), bias, options);
            }
            Weights::Planar(w) => w[layer].clone(),
        };
        let [b, c, _, h, width] = x.dims();
        let options = ConvOptions::new([2, 2], [1, 1], [1, 1], 1);
        let y = conv2d(x.reshape([b, c, h, width]), w, bias, options); // [b, o, h / 2, w / 2]
        let [_, o, h2, w2] = y.dims();
        y.reshape([b, o, 1, h2, w2])
    }

    /// The transpose of [`Critic::conv`]'s linear part (same weights, no bias).
    ///
    /// # Shapes
    /// - `g`: `[batch, out, depth / 2, rows / 2, cols / 2]`
    /// - output: `[batch, in, depth, rows, cols]`
    fn conv_transpose(&self, weights: &Weights, layer: usize, g: Tensor<5>) -> Tensor<5> {
        let w = match weights {
            Weights::Volumetric(w) => {
                let options = ConvTransposeOptions::new([2; 3], [1; 3], [0; 3], [1; 3], 1);
                return conv_transpose3d(g, w[layer].clone(), None, options);
            }
            Weights::Planar(w) => w[layer].clone(),
        };
        let [b, c, _, h, width] = g.dims();
        let options = ConvTransposeOptions::new([2, 2], [1, 1], [0, 0], [1, 1], 1);
        let x = conv_transpose2d(g.reshape([b, c, h, width]), w, None, options); // [b, in, 2h, 2w]
        let [_, i, h2, w2] = x.dims();
        x.reshape([b, i, 1, h2, w2])
    }

    /// Scores a batch.
    ///
    /// # Shapes
    /// - `x`: `[batch, channels, depth, crop, crop]` (depth 1 in 2D, else crop)
    /// - output: `[batch, 1]`
    pub fn forward(&self, x: Tensor<5>) -> Tensor<2> {
        self.score(&self.weights(), x)
    }

    /// [`Critic::forward`] with weights made once by [`Critic::weights`].
    pub fn score(&self, weights: &Weights, x: Tensor<5>) -> Tensor<2> {
        self.forward_with_masks(weights, x, false).0
    }

    /// The detached LeakyReLU slope masks of every layer at `x` (1 where the pre-activation is
    /// positive, `slope` elsewhere): the linear region D is in.
    pub fn activation_masks(&self, x: Tensor<5>) -> Vec<Tensor<5>> {
        self.forward_with_masks(&self.weights(), x, true).1
    }

    /// Forward pass that also returns each layer's detached LeakyReLU slope mask when `masks`
    /// is set.
    fn forward_with_masks(
        &self,
        weights: &Weights,
        x: Tensor<5>,
        masks: bool,
    ) -> (Tensor<2>, Vec<Tensor<5>>) {
        let mut h = x;
        let mut slopes = Vec::new();
        for layer in 0..self.convs.len() {
            let z = self.conv(weights, layer, h); // [b, w, d/2, s/2, s/2]
            if masks {
                let positive = z.clone().detach().greater_elem(0.0).float();
                slopes.push(positive * (1.0 - self.slope) + self.slope);
            }
            h = leaky_relu(z, self.slope);
        }
        let [b, c, d, s, t] = h.dims();
        let score = self.head.forward(h.reshape([b, c * d * s * t])); // [b, 1]
        (score, slopes)
    }

    /// The exact gradient of D's score with respect to its input, for each sample, as a function
    /// of the weights that first-order autodiff can differentiate.
    ///
    /// # Shapes
    /// - `x`: `[batch, channels, depth, crop, crop]`
    /// - output: the same
    pub fn input_gradient(&self, weights: &Weights, x: Tensor<5>) -> Tensor<5> {
        let [b, ..] = x.dims();
        // The masks need no graph: on an autodiff device compute them on the inner backend.
        let masks: Vec<Tensor<5>> = if x.device().is_autodiff() {
            self.valid()
                .activation_masks(x.inner())
                .into_iter()
                .map(Tensor::from_inner)
                .collect()
        } else {
            self.activation_masks(x)
        };
        let last = masks.last().expect("critic has convolutions");
        let [_, c, d, s, t] = last.dims();
        // d score / d (last activation) is the head's weight, the same for every sample.
        let mut g = self
            .head
            .weight
            .val()
            .reshape([1, c, d, s, t])
            .repeat_dim(0, b); // [b, c, d, s, t]
        for (layer, mask) in masks.iter().enumerate().rev() {
            g = g * mask.clone(); // through the LeakyReLU
            g = self.conv_transpose(weights, layer, g); // through the convolution
        }
        g
    }

    /// WGAN-GP penalty `lambda * mean_b (||dD/dx(x_hat_b)|| - 1)^2` at `x_hat = alpha * real +
    /// (1 - alpha) * fake`, with one `alpha` per sample. `real` and `fake` should be detached.
    ///
    /// # Shapes
    /// - `real`, `fake`: `[batch, channels, depth, crop, crop]`
    /// - `alpha`: `[batch]`
    /// - output: `[1]`
    pub fn gradient_penalty(
        &self,
        weights: &Weights,
        real: Tensor<5>,
        fake: Tensor<5>,
        alpha: Tensor<1>,
        lambda: f64,
    ) -> Tensor<1> {
        let [b, ..] = real.dims();
        let alpha = alpha.reshape([b, 1, 1, 1, 1]);
        let x_hat = real * alpha.clone() + fake * (alpha.neg() + 1.0);
        let g = self.input_gradient(weights, x_hat); // [b, c, d, h, w]
        let [_, c, d, h, w] = g.dims();
        let norm = (g.powi_scalar(2).reshape([b, c * d * h * w]).sum_dim(1) + 1e-12).sqrt(); // [b, 1]
        ((norm - 1.0).powi_scalar(2)).mean() * lambda
    }
}
