//! The critic D (DCGAN-style, no normalisation) and its exact input gradient.
//!
//! D = head ∘ flatten ∘ (leaky ∘ conv_4) ∘ ... ∘ (leaky ∘ conv_1), each convolution kernel 4,
//! stride 2, padding 1, LeakyReLU slope 0.01, then one linear layer to a score.
//!
//! WGAN-GP needs `||dD/dx||` and its gradient with respect to D's weights. burn has no
//! second-order autodiff, but D is piecewise linear, so
//! `dD/dx = W_1^T M_1 W_2^T M_2 ... W_4^T M_4 w_head`, where `M_l` is the (detached) LeakyReLU
//! slope mask of layer l and `W_l^T` is a transposed convolution with the same weights.
//! [`Critic::input_gradient`] builds that product from ordinary tensor ops, so first-order
//! autodiff differentiates the penalty with respect to the weights exactly.

use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{Linear, LinearConfig, PaddingConfig2d};
use burn::prelude::*;
use burn::tensor::activation::leaky_relu;
use burn::tensor::module::{conv_transpose2d, conv2d};
use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};

use crate::input_error;

pub mod volume;

/// Shape of a critic. The crop must be a multiple of 2^(number of convolutions).
#[derive(Config, Debug, PartialEq)]
pub struct CriticConfig {
    /// Input channels (the exemplar's).
    pub channels: usize,
    /// Input width and height in pixels.
    pub crop: usize,
    /// Output channels of each stride-2 convolution.
    #[config(default = "vec![64, 128, 256, 512]")]
    pub widths: Vec<usize>,
    /// Negative slope of the LeakyReLU (the authors' code uses PyTorch's default, 0.01).
    #[config(default = 0.01)]
    pub slope: f64,
}

impl CriticConfig {
    /// Side of the last feature map.
    pub fn final_side(&self) -> usize {
        self.crop >> self.widths.len()
    }

    pub fn validate(&self) -> crate::Result<()> {
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
        let mut inputs = self.channels;
        let convs = self
            .widths
            .iter()
            .map(|&w| {
                let conv = Conv2dConfig::new([inputs, w], [4, 4])
                    .with_stride([2, 2])
                    .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                    .init(device);
                inputs = w;
                conv
            })
            .collect();
        let side = self.final_side();
        Critic {
            convs,
            head: LinearConfig::new(inputs * side * side, 1).init(device),
            slope: self.slope,
        }
    }
}

/// The critic as a burn module.
#[derive(Module, Debug)]
pub struct Critic {
    pub convs: Vec<Conv2d>,
    pub head: Linear,
    pub slope: f64,
}

fn conv_options() -> ConvOptions<2> {
    ConvOptions::new([2, 2], [1, 1], [1, 1], 1)
}

impl Critic {
    /// Scores a batch.
    ///
    /// # Shapes
    /// - `x`: `[batch, channels, crop, crop]`
    /// - output: `[batch, 1]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<2> {
        self.forward_with_masks(x, false).0
    }

    /// The detached LeakyReLU slope masks of every layer at `x` (1 where the pre-activation is
    /// positive, `slope` elsewhere): the linear region D is in.
    pub fn activation_masks(&self, x: Tensor<4>) -> Vec<Tensor<4>> {
        self.forward_with_masks(x, true).1
    }

    /// Forward pass that also returns each layer's detached LeakyReLU slope mask
    /// (1 where the pre-activation is positive, `slope` elsewhere) when `masks` is set.
    fn forward_with_masks(&self, x: Tensor<4>, masks: bool) -> (Tensor<2>, Vec<Tensor<4>>) {
        let mut h = x;
        let mut slopes = Vec::new();
        for conv in &self.convs {
            let z = conv2d(
                h,
                conv.weight.val(),
                conv.bias.as_ref().map(|b| b.val()),
                conv_options(),
            ); // [b, w, s/2, s/2]
            if masks {
                let positive = z.clone().detach().greater_elem(0.0).float();
                slopes.push(positive * (1.0 - self.slope) + self.slope);
            }
            h = leaky_relu(z, self.slope);
        }
        let [b, c, s, _] = h.dims();
        let score = self.head.forward(h.reshape([b, c * s * s])); // [b, 1]
        (score, slopes)
    }

    /// The exact gradient of D's score with respect to its input, for each sample, as a function
    /// of the weights that first-order autodiff can differentiate.
    ///
    /// # Shapes
    /// - `x`: `[batch, channels, crop, crop]`
    /// - output: `[batch, channels, crop, crop]`
    pub fn input_gradient(&self, x: Tensor<4>) -> Tensor<4> {
        let [b, ..] = x.dims();
        // The masks need no graph: on an autodiff device compute them on the inner backend.
        let masks: Vec<Tensor<4>> = if x.device().is_autodiff() {
            self.valid()
                .activation_masks(x.inner())
                .into_iter()
                .map(Tensor::from_inner)
                .collect()
        } else {
            self.activation_masks(x)
        };
        let last = masks.last().expect("critic has convolutions");
        let [_, c, s, _] = last.dims();
        // d score / d (last activation) is the head's weight, the same for every sample.
        let head = self
            .head
            .weight
            .val()
            .reshape([1, c, s, s])
            .repeat_dim(0, b); // [b, c, s, s]
        let mut g = head;
        for (conv, mask) in self.convs.iter().zip(&masks).rev() {
            g = g * mask.clone(); // through the LeakyReLU
            // through the convolution: its transpose, same weights [out, in, 4, 4]
            g = conv_transpose2d(
                g,
                conv.weight.val(),
                None,
                ConvTransposeOptions::new([2, 2], [1, 1], [0, 0], [1, 1], 1),
            );
        }
        g
    }

    /// WGAN-GP penalty `lambda * mean_b (||dD/dx(x_hat_b)|| - 1)^2` at `x_hat = alpha * real +
    /// (1 - alpha) * fake`, with one `alpha` per sample. `real` and `fake` should be detached.
    ///
    /// # Shapes
    /// - `real`, `fake`: `[batch, channels, crop, crop]`
    /// - `alpha`: `[batch]`
    /// - output: `[1]`
    pub fn gradient_penalty(
        &self,
        real: Tensor<4>,
        fake: Tensor<4>,
        alpha: Tensor<1>,
        lambda: f64,
    ) -> Tensor<1> {
        let [b, ..] = real.dims();
        let alpha = alpha.reshape([b, 1, 1, 1]);
        let x_hat = real * alpha.clone() + fake * (alpha.neg() + 1.0);
        let g = self.input_gradient(x_hat); // [b, c, h, w]
        let [_, c, h, w] = g.dims();
        let norm = (g.powi_scalar(2).reshape([b, c * h * w]).sum_dim(1) + 1e-12).sqrt(); // [b, 1]
        ((norm - 1.0).powi_scalar(2)).mean() * lambda
    }
}

#[cfg(test)]
mod tests {
    //! Finite-difference checks of the exact gradient penalty (DESIGN.md §2). Any change to the
    //! critic must keep these passing. D is piecewise linear, so differences are exact within a
    //! linear region: steps that flip a LeakyReLU mask are detected and skipped.
    use super::*;
    use crate::checkpoint::{Checkpoint, read_module, write_module};
    use crate::latent::derive_seed;

    fn values(n: usize, seed: u64, scale: f32) -> Vec<f32> {
        (0..n as u64)
            .map(|i| ((derive_seed(seed, &[i]) >> 40) as f32 / 16_777_216.0 * 2.0 - 1.0) * scale)
            .collect()
    }

    fn small_critic(device: &Device) -> Critic {
        let critic = CriticConfig::new(3, 16)
            .with_widths(vec![4, 6, 8, 8])
            .init(device);
        let mut ckpt = Checkpoint::new();
        write_module(&critic, "c", &mut ckpt);
        for (i, t) in ckpt.tensors.values_mut().enumerate() {
            t.values = values(t.values.len(), 100 + i as u64, 0.4);
        }
        read_module(critic, "c", &ckpt).unwrap()
    }

    fn input(seed: u64, device: &Device) -> Tensor<4> {
        Tensor::from_data(
            TensorData::new(values(2 * 3 * 16 * 16, seed, 1.0), [2, 3, 16, 16]),
            device,
        )
    }

    fn same_masks(a: &[Tensor<4>], b: &[Tensor<4>]) -> bool {
        a.iter()
            .zip(b)
            .all(|(x, y)| x.clone().equal(y.clone()).all().into_scalar::<bool>())
    }

    #[test]
    fn input_gradient_matches_finite_differences() {
        let device = Device::flex();
        let critic = small_critic(&device);
        let x = input(1, &device);
        let analytic = critic
            .input_gradient(x.clone())
            .try_into_vec_as::<f32>()
            .unwrap();
        let base = x.try_into_vec_as::<f32>().unwrap();
        let masks = critic.activation_masks(input(1, &device));
        let score = |v: &[f32]| -> (f32, Vec<Tensor<4>>) {
            let t = Tensor::<4>::from_data(TensorData::new(v.to_vec(), [2, 3, 16, 16]), &device);
            (
                critic.forward(t.clone()).sum().into_scalar::<f32>(),
                critic.activation_masks(t),
            )
        };
        let h = 1e-2;
        let (mut checked, mut worst) = (0, 0f32);
        for k in (0..base.len()).step_by(37) {
            let (mut plus, mut minus) = (base.clone(), base.clone());
            plus[k] += h;
            minus[k] -= h;
            let ((dp, mp), (dm, mm)) = (score(&plus), score(&minus));
            if !same_masks(&mp, &masks) || !same_masks(&mm, &masks) {
                continue;
            }
            let fd = (dp - dm) / (2.0 * h);
            let err = (fd - analytic[k]).abs() / analytic[k].abs().max(1e-2);
            worst = worst.max(err);
            checked += 1;
        }
        eprintln!("dD/dx: checked {checked}, worst {worst:e}");
        assert!(checked > 30, "too few coordinates checked ({checked})");
        assert!(
            worst < 5e-3,
            "dD/dx differs from finite differences by {worst} (relative)"
        );
    }

    #[test]
    fn penalty_weight_gradient_matches_finite_differences() {
        let plain = Device::flex();
        let device = plain.clone().autodiff();
        let critic = small_critic(&device);
        let (real, fake) = (input(2, &device), input(3, &device));
        let alpha = Tensor::<1>::from_data(TensorData::new(vec![0.3f32, 0.8], [2]), &device);
        let penalty = critic.gradient_penalty(real.clone(), fake.clone(), alpha.clone(), 10.0);
        let grads = penalty.backward();
        let mut analytic = Checkpoint::new();
        for (i, conv) in critic.convs.iter().enumerate() {
            let g = conv
                .weight
                .val()
                .grad(&grads)
                .expect("conv weight has a gradient");
            let shape = g.dims().to_vec();
            analytic.insert(
                format!("c.convs.{i}.weight"),
                shape,
                g.try_into_vec_as::<f32>().unwrap(),
            );
        }
        let g = critic
            .head
            .weight
            .val()
            .grad(&grads)
            .expect("head weight has a gradient");
        analytic.insert(
            "c.head.weight",
            g.dims().to_vec(),
            g.try_into_vec_as::<f32>().unwrap(),
        );

        let mut weights = Checkpoint::new();
        write_module(&critic.valid(), "c", &mut weights);
        let x_hat = |c: &Critic| {
            let a = alpha.clone().inner().reshape([2, 1, 1, 1]);
            c.activation_masks(
                real.clone().inner() * a.clone() + fake.clone().inner() * (a.neg() + 1.0),
            )
        };
        let base_masks = x_hat(&critic.valid());
        let evaluate = |ckpt: &Checkpoint| -> (f32, Vec<Tensor<4>>) {
            let c = read_module(critic.valid(), "c", ckpt).unwrap();
            let p = c.gradient_penalty(
                real.clone().inner(),
                fake.clone().inner(),
                alpha.clone().inner(),
                10.0,
            );
            (p.into_scalar::<f32>(), x_hat(&c))
        };
        let h = 2e-3;
        let (mut checked, mut worst) = (0, 0f32);
        for (name, grad) in &analytic.tensors {
            for k in (0..grad.values.len()).step_by(grad.values.len() / 6 + 1) {
                let (mut plus, mut minus) = (weights.clone(), weights.clone());
                plus.tensors.get_mut(name).unwrap().values[k] += h;
                minus.tensors.get_mut(name).unwrap().values[k] -= h;
                let ((pp, mp), (pm, mm)) = (evaluate(&plus), evaluate(&minus));
                if !same_masks(&mp, &base_masks) || !same_masks(&mm, &base_masks) {
                    continue;
                }
                let fd = (pp - pm) / (2.0 * h);
                let a = grad.values[k];
                let err = (fd - a).abs() / a.abs().max(1e-1);
                worst = worst.max(err);
                checked += 1;
            }
        }
        eprintln!("dP/dW: checked {checked}, worst {worst:e}");
        assert!(checked >= 20, "too few weights checked ({checked})");
        assert!(
            worst < 1e-2,
            "d(penalty)/dW differs from finite differences by {worst} (relative)"
        );
    }
}
