//! The 3D critic for volumes (paper §4.2: signed-distance volumes), and its exact input
//! gradient, by the same construction as the 2D critic: D is piecewise linear, so
//! `dD/dx = W_1^T M_1 ... W_4^T M_4 w_head` with detached LeakyReLU masks `M_l` and transposed
//! 3D convolutions `W_l^T` ([`VolumeCritic::input_gradient`]).
//!
//! Convolutions: kernel 4, stride 2, padding 1 on every axis, so a crop of `s` voxels per side
//! ends at `s / 2^layers`.

use burn::nn::conv::{Conv3d, Conv3dConfig};
use burn::nn::{Linear, LinearConfig, PaddingConfig3d};
use burn::prelude::*;
use burn::tensor::activation::leaky_relu;
use burn::tensor::module::{conv_transpose3d, conv3d};
use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};

use crate::input_error;

/// Shape of a volume critic. The crop must be a multiple of 2^(number of convolutions).
#[derive(Config, Debug, PartialEq)]
pub struct VolumeCriticConfig {
    /// Input channels (1 for a signed-distance volume).
    pub channels: usize,
    /// Input side in voxels (crops are cubes; 32 or 64 in the paper's setting).
    pub crop: usize,
    /// Output channels of each stride-2 convolution.
    #[config(default = "vec![32, 64, 128, 256]")]
    pub widths: Vec<usize>,
    /// Negative slope of the LeakyReLU.
    #[config(default = 0.01)]
    pub slope: f64,
}

impl VolumeCriticConfig {
    /// Side of the last feature volume.
    pub fn final_side(&self) -> usize {
        self.crop >> self.widths.len()
    }

    pub fn validate(&self) -> crate::Result<()> {
        let factor = 1usize << self.widths.len();
        if self.crop == 0 || !self.crop.is_multiple_of(factor) {
            return Err(input_error!(
                "crop {}: the volume critic halves the crop {} times, so it must be a positive multiple of {factor} (e.g. --crop {})",
                self.crop,
                self.widths.len(),
                (self.crop.max(factor) / factor) * factor
            ));
        }
        Ok(())
    }

    /// A critic with PyTorch-style uniform initialisation on `device`.
    pub fn init(&self, device: &Device) -> VolumeCritic {
        let mut inputs = self.channels;
        let convs = self
            .widths
            .iter()
            .map(|&w| {
                let conv = Conv3dConfig::new([inputs, w], [4, 4, 4])
                    .with_stride([2, 2, 2])
                    .with_padding(PaddingConfig3d::Explicit(1, 1, 1))
                    .init(device);
                inputs = w;
                conv
            })
            .collect();
        let side = self.final_side();
        VolumeCritic {
            convs,
            head: LinearConfig::new(inputs * side * side * side, 1).init(device),
            slope: self.slope,
        }
    }
}

/// The volume critic as a burn module.
#[derive(Module, Debug)]
pub struct VolumeCritic {
    pub convs: Vec<Conv3d>,
    pub head: Linear,
    pub slope: f64,
}

fn conv_options() -> ConvOptions<3> {
    ConvOptions::new([2, 2, 2], [1, 1, 1], [1, 1, 1], 1)
}

impl VolumeCritic {
    /// Scores a batch.
    ///
    /// # Shapes
    /// - `x`: `[batch, channels, crop, crop, crop]`
    /// - output: `[batch, 1]`
    pub fn forward(&self, x: Tensor<5>) -> Tensor<2> {
        self.forward_with_masks(x, false).0
    }

    /// The detached LeakyReLU slope masks of every layer at `x`.
    pub fn activation_masks(&self, x: Tensor<5>) -> Vec<Tensor<5>> {
        self.forward_with_masks(x, true).1
    }

    fn forward_with_masks(&self, x: Tensor<5>, masks: bool) -> (Tensor<2>, Vec<Tensor<5>>) {
        let mut h = x;
        let mut slopes = Vec::new();
        for conv in &self.convs {
            let z = conv3d(
                h,
                conv.weight.val(),
                conv.bias.as_ref().map(|b| b.val()),
                conv_options(),
            ); // [b, w, s/2, s/2, s/2]
            if masks {
                let positive = z.clone().detach().greater_elem(0.0).float();
                slopes.push(positive * (1.0 - self.slope) + self.slope);
            }
            h = leaky_relu(z, self.slope);
        }
        let [b, c, s, ..] = h.dims();
        let score = self.head.forward(h.reshape([b, c * s * s * s])); // [b, 1]
        (score, slopes)
    }

    /// The exact gradient of D's score with respect to its input, differentiable with respect
    /// to the weights by first-order autodiff.
    ///
    /// # Shapes
    /// - `x`: `[batch, channels, crop, crop, crop]`
    /// - output: `[batch, channels, crop, crop, crop]`
    pub fn input_gradient(&self, x: Tensor<5>) -> Tensor<5> {
        let [b, ..] = x.dims();
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
        let [_, c, s, ..] = last.dims();
        let mut g = self
            .head
            .weight
            .val()
            .reshape([1, c, s, s, s])
            .repeat_dim(0, b); // [b, c, s, s, s]
        for (conv, mask) in self.convs.iter().zip(&masks).rev() {
            g = g * mask.clone(); // through the LeakyReLU
            g = conv_transpose3d(
                g,
                conv.weight.val(),
                None,
                ConvTransposeOptions::new([2, 2, 2], [1, 1, 1], [0, 0, 0], [1, 1, 1], 1),
            ); // through the convolution
        }
        g
    }

    /// WGAN-GP penalty `lambda * mean_b (||dD/dx(x_hat_b)|| - 1)^2` at
    /// `x_hat = alpha * real + (1 - alpha) * fake`.
    ///
    /// # Shapes
    /// - `real`, `fake`: `[batch, channels, crop, crop, crop]`
    /// - `alpha`: `[batch]`
    /// - output: `[1]`
    pub fn gradient_penalty(
        &self,
        real: Tensor<5>,
        fake: Tensor<5>,
        alpha: Tensor<1>,
        lambda: f64,
    ) -> Tensor<1> {
        let [b, ..] = real.dims();
        let alpha = alpha.reshape([b, 1, 1, 1, 1]);
        let x_hat = real * alpha.clone() + fake * (alpha.neg() + 1.0);
        let g = self.input_gradient(x_hat);
        let [_, c, d, h, w] = g.dims();
        let norm = (g.powi_scalar(2).reshape([b, c * d * h * w]).sum_dim(1) + 1e-12).sqrt();
        ((norm - 1.0).powi_scalar(2)).mean() * lambda
    }
}

#[cfg(test)]
mod tests {
    //! The 2D critic's finite-difference checks, in 3D.
    use super::*;
    use crate::checkpoint::{Checkpoint, read_module, write_module};
    use crate::latent::derive_seed;

    const SHAPE: [usize; 5] = [2, 1, 16, 16, 16];

    fn values(n: usize, seed: u64, scale: f32) -> Vec<f32> {
        (0..n as u64)
            .map(|i| ((derive_seed(seed, &[i]) >> 40) as f32 / 16_777_216.0 * 2.0 - 1.0) * scale)
            .collect()
    }

    fn small_critic(device: &Device) -> VolumeCritic {
        let critic = VolumeCriticConfig::new(1, 16)
            .with_widths(vec![3, 4, 5, 6])
            .init(device);
        let mut ckpt = Checkpoint::new();
        write_module(&critic, "c", &mut ckpt);
        for (i, t) in ckpt.tensors.values_mut().enumerate() {
            t.values = values(t.values.len(), 200 + i as u64, 0.4);
        }
        read_module(critic, "c", &ckpt).unwrap()
    }

    fn input(seed: u64, device: &Device) -> Tensor<5> {
        Tensor::from_data(
            TensorData::new(values(SHAPE.iter().product(), seed, 1.0), SHAPE),
            device,
        )
    }

    fn same_masks(a: &[Tensor<5>], b: &[Tensor<5>]) -> bool {
        a.iter()
            .zip(b)
            .all(|(x, y)| x.clone().equal(y.clone()).all().into_scalar::<bool>())
    }

    #[test]
    fn volume_input_gradient_matches_finite_differences() {
        let device = Device::flex();
        let critic = small_critic(&device);
        let x = input(1, &device);
        let analytic = critic
            .input_gradient(x.clone())
            .try_into_vec_as::<f32>()
            .unwrap();
        let base = x.try_into_vec_as::<f32>().unwrap();
        let masks = critic.activation_masks(input(1, &device));
        let score = |v: &[f32]| -> (f32, Vec<Tensor<5>>) {
            let t = Tensor::<5>::from_data(TensorData::new(v.to_vec(), SHAPE), &device);
            (
                critic.forward(t.clone()).sum().into_scalar::<f32>(),
                critic.activation_masks(t),
            )
        };
        let h = 1e-2;
        let (mut checked, mut worst) = (0, 0f32);
        for k in (0..base.len()).step_by(211) {
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
        eprintln!("3D dD/dx: checked {checked}, worst {worst:e}");
        assert!(checked > 20, "too few coordinates checked ({checked})");
        assert!(
            worst < 5e-3,
            "3D dD/dx differs from finite differences by {worst}"
        );
    }

    #[test]
    fn volume_penalty_weight_gradient_matches_finite_differences() {
        let device = Device::flex().autodiff();
        let critic = small_critic(&device);
        let (real, fake) = (input(2, &device), input(3, &device));
        let alpha = Tensor::<1>::from_data(TensorData::new(vec![0.3f32, 0.8], [2]), &device);
        let penalty = critic.gradient_penalty(real.clone(), fake.clone(), alpha.clone(), 10.0);
        let grads = penalty.backward();
        let analytic: Vec<Vec<f32>> = critic
            .convs
            .iter()
            .map(|conv| {
                conv.weight
                    .val()
                    .grad(&grads)
                    .expect("conv weight has a gradient")
                    .try_into_vec_as::<f32>()
                    .unwrap()
            })
            .collect();

        let mut weights = Checkpoint::new();
        write_module(&critic.valid(), "c", &mut weights);
        let x_hat_masks = |c: &VolumeCritic| {
            let a = alpha.clone().inner().reshape([2, 1, 1, 1, 1]);
            c.activation_masks(
                real.clone().inner() * a.clone() + fake.clone().inner() * (a.neg() + 1.0),
            )
        };
        let base_masks = x_hat_masks(&critic.valid());
        let evaluate = |ckpt: &Checkpoint| -> (f32, Vec<Tensor<5>>) {
            let c = read_module(critic.valid(), "c", ckpt).unwrap();
            let p = c.gradient_penalty(
                real.clone().inner(),
                fake.clone().inner(),
                alpha.clone().inner(),
                10.0,
            );
            (p.into_scalar::<f32>(), x_hat_masks(&c))
        };
        // The penalty is about 22 here, whose f32 ulp is 2e-6, so central differences carry
        // about ulp / h of rounding noise: h = 1e-2 keeps it near 2e-4, while the truncation
        // error stays O(h^2) (steps that flip a mask are skipped).
        let h = 1e-2;
        let (mut checked, mut worst) = (0, 0f32);
        for (layer, grad) in analytic.iter().enumerate() {
            let name = format!("c.convs.{layer}.weight");
            for k in (0..grad.len()).step_by(grad.len() / 6 + 1) {
                let (mut plus, mut minus) = (weights.clone(), weights.clone());
                plus.tensors.get_mut(&name).unwrap().values[k] += h;
                minus.tensors.get_mut(&name).unwrap().values[k] -= h;
                let ((pp, mp), (pm, mm)) = (evaluate(&plus), evaluate(&minus));
                if !same_masks(&mp, &base_masks) || !same_masks(&mm, &base_masks) {
                    continue;
                }
                let fd = (pp - pm) / (2.0 * h);
                let err = (fd - grad[k]).abs() / grad[k].abs().max(1e-1);
                worst = worst.max(err);
                checked += 1;
            }
        }
        eprintln!("3D d(penalty)/dW: checked {checked}, worst {worst:e}");
        assert!(checked > 10, "too few weights checked ({checked})");
        assert!(
            worst < 1e-2,
            "3D penalty gradient differs from finite differences by {worst}"
        );
    }
}
