//! Finite-difference checks of the exact gradient penalty (the book's design notes), one body run on 2 and
//! 3 axes. Any change to the critic must keep these passing. D is piecewise linear, so
//! differences are exact within a linear region: steps that flip a LeakyReLU mask are detected
//! and skipped.
use super::*;
use crate::checkpoint::{Checkpoint, read_module, write_module};
use crate::latent::derive_seed;

/// One critic under test and the tolerances of its checks.
struct Case {
    axes: usize,
    channels: usize,
    widths: Vec<usize>,
    /// Seed of the weights' values.
    weight_seed: u64,
    /// Every this-many-th input coordinate is checked.
    input_stride: usize,
    min_inputs_checked: usize,
    /// Step of the weight differences: the 3D penalty is about 22, whose f32 ulp is 2e-6, so
    /// central differences carry about ulp / h of rounding noise; 1e-2 keeps it near 2e-4 while
    /// the truncation error stays O(h^2).
    weight_step: f32,
    min_weights_checked: usize,
    /// Also check the head's weight (the 2D case always did).
    head: bool,
}

fn image_case() -> Case {
    Case {
        axes: 2,
        channels: 3,
        widths: vec![4, 6, 8, 8],
        weight_seed: 100,
        input_stride: 37,
        min_inputs_checked: 31,
        weight_step: 2e-3,
        min_weights_checked: 20,
        head: true,
    }
}

fn volume_case() -> Case {
    Case {
        axes: 3,
        channels: 1,
        widths: vec![3, 4, 5, 6],
        weight_seed: 200,
        input_stride: 211,
        min_inputs_checked: 21,
        weight_step: 1e-2,
        min_weights_checked: 11,
        head: false,
    }
}

impl Case {
    fn shape(&self) -> [usize; 5] {
        let depth = if self.axes == 3 { 16 } else { 1 };
        [2, self.channels, depth, 16, 16]
    }

    fn critic(&self, device: &Device) -> Critic {
        let critic = CriticConfig::new(self.channels, 16)
            .with_axes(self.axes)
            .with_widths(self.widths.clone())
            .init(device);
        let mut ckpt = Checkpoint::new();
        write_module(&critic, "c", &mut ckpt);
        for (i, t) in ckpt.tensors.values_mut().enumerate() {
            t.values = values(t.values.len(), self.weight_seed + i as u64, 0.4);
        }
        read_module(critic, "c", &ckpt).unwrap()
    }

    fn input(&self, seed: u64, device: &Device) -> Tensor<5> {
        let shape = self.shape();
        Tensor::from_data(
            TensorData::new(values(shape.iter().product(), seed, 1.0), shape),
            device,
        )
    }
}

fn values(n: usize, seed: u64, scale: f32) -> Vec<f32> {
    (0..n as u64)
        .map(|i| ((derive_seed(seed, &[i]) >> 40) as f32 / 16_777_216.0 * 2.0 - 1.0) * scale)
        .collect()
}

fn same_masks(a: &[Tensor<5>], b: &[Tensor<5>]) -> bool {
    a.iter()
        .zip(b)
        .all(|(x, y)| x.clone().equal(y.clone()).all().into_scalar::<bool>())
}

/// Central differences against an analytic gradient: how many were checked, and the worst
/// relative error.
#[derive(Default)]
struct Tally {
    checked: usize,
    worst: f32,
}

impl Tally {
    /// Counts the difference `(plus - minus) / 2h` against `analytic`, relative to
    /// `|analytic|` but at least `floor`.
    fn add(&mut self, [plus, minus]: [f32; 2], h: f32, analytic: f32, floor: f32) {
        let fd = (plus - minus) / (2.0 * h);
        self.worst = self
            .worst
            .max((fd - analytic).abs() / analytic.abs().max(floor));
        self.checked += 1;
    }

    fn assert_within(&self, what: &str, min_checked: usize, tolerance: f32) {
        let Tally { checked, worst } = self;
        eprintln!("{what}: checked {checked}, worst {worst:e}");
        assert!(
            *checked >= min_checked,
            "{what}: too few checked ({checked})"
        );
        assert!(
            *worst < tolerance,
            "{what} differs from finite differences by {worst} (relative)"
        );
    }
}

fn input_gradient_matches_finite_differences(case: Case) {
    let device = Device::flex();
    let critic = case.critic(&device);
    let x = case.input(1, &device);
    let analytic = critic
        .input_gradient(&critic.weights(), x.clone())
        .try_into_vec_as::<f32>()
        .unwrap();
    let base = x.try_into_vec_as::<f32>().unwrap();
    let masks = critic.activation_masks(case.input(1, &device));
    let score = |v: &[f32]| -> (f32, Vec<Tensor<5>>) {
        let t = Tensor::<5>::from_data(TensorData::new(v.to_vec(), case.shape()), &device);
        (
            critic.forward(t.clone()).sum().into_scalar::<f32>(),
            critic.activation_masks(t),
        )
    };
    let h = 1e-2;
    let mut tally = Tally::default();
    for k in (0..base.len()).step_by(case.input_stride) {
        let (mut plus, mut minus) = (base.clone(), base.clone());
        plus[k] += h;
        minus[k] -= h;
        let ((dp, mp), (dm, mm)) = (score(&plus), score(&minus));
        if !same_masks(&mp, &masks) || !same_masks(&mm, &masks) {
            continue;
        }
        tally.add([dp, dm], h, analytic[k], 1e-2);
    }
    let what = format!("{}D dD/dx", case.axes);
    tally.assert_within(&what, case.min_inputs_checked, 5e-3);
}

/// The analytic gradient of the penalty with respect to every checked weight tensor.
fn penalty_gradients(case: &Case, critic: &Critic, penalty: Tensor<1>) -> Checkpoint {
    let grads = penalty.backward();
    let mut analytic = Checkpoint::new();
    let mut add = |name: String, g: Tensor<5>| {
        let shape = g.dims().to_vec();
        analytic.insert(name, shape, g.try_into_vec_as::<f32>().unwrap());
    };
    for (i, conv) in critic.convs.iter().enumerate() {
        let g = conv
            .weight
            .val()
            .grad(&grads)
            .expect("conv weight has a gradient");
        add(format!("c.convs.{i}.weight"), g);
    }
    if case.head {
        let g = critic
            .head
            .weight
            .val()
            .grad(&grads)
            .expect("head weight has a gradient");
        let [i, o] = g.dims();
        add("c.head.weight".into(), g.reshape([i, o, 1, 1, 1]));
    }
    analytic
}

fn penalty_weight_gradient_matches_finite_differences(case: Case) {
    let device = Device::flex().autodiff();
    let critic = case.critic(&device);
    let (real, fake) = (case.input(2, &device), case.input(3, &device));
    let alpha = Tensor::<1>::from_data(TensorData::new(vec![0.3f32, 0.8], [2]), &device);
    let penalty = critic.gradient_penalty(
        &critic.weights(),
        real.clone(),
        fake.clone(),
        alpha.clone(),
        10.0,
    );
    let analytic = penalty_gradients(&case, &critic, penalty);

    let mut weights = Checkpoint::new();
    write_module(&critic.valid(), "c", &mut weights);
    let x_hat_masks = |c: &Critic| {
        let a = alpha.clone().inner().reshape([2, 1, 1, 1, 1]);
        c.activation_masks(
            real.clone().inner() * a.clone() + fake.clone().inner() * (a.neg() + 1.0),
        )
    };
    let base_masks = x_hat_masks(&critic.valid());
    let evaluate = |ckpt: &Checkpoint| -> (f32, Vec<Tensor<5>>) {
        let c = read_module(critic.valid(), "c", ckpt).unwrap();
        let p = c.gradient_penalty(
            &c.weights(),
            real.clone().inner(),
            fake.clone().inner(),
            alpha.clone().inner(),
            10.0,
        );
        (p.into_scalar::<f32>(), x_hat_masks(&c))
    };
    let h = case.weight_step;
    let mut tally = Tally::default();
    for (name, grad) in &analytic.tensors {
        for k in (0..grad.values.len()).step_by(grad.values.len() / 6 + 1) {
            let (mut plus, mut minus) = (weights.clone(), weights.clone());
            plus.tensors.get_mut(name).unwrap().values[k] += h;
            minus.tensors.get_mut(name).unwrap().values[k] -= h;
            let ((pp, mp), (pm, mm)) = (evaluate(&plus), evaluate(&minus));
            if !same_masks(&mp, &base_masks) || !same_masks(&mm, &base_masks) {
                continue;
            }
            tally.add([pp, pm], h, grad.values[k], 1e-1);
        }
    }
    let what = format!("{}D d(penalty)/dW", case.axes);
    tally.assert_within(&what, case.min_weights_checked, 1e-2);
}

#[test]
fn input_gradient_matches_finite_differences_2d() {
    input_gradient_matches_finite_differences(image_case());
}

#[test]
fn input_gradient_matches_finite_differences_3d() {
    input_gradient_matches_finite_differences(volume_case());
}

#[test]
fn penalty_weight_gradient_matches_finite_differences_2d() {
    penalty_weight_gradient_matches_finite_differences(image_case());
}

#[test]
fn penalty_weight_gradient_matches_finite_differences_3d() {
    penalty_weight_gradient_matches_finite_differences(volume_case());
}

#[test]
fn a_2d_critic_reads_weights_stored_without_the_depth_axis() {
    // Run folders written before the critic was one type hold [out, in, k, k] weights.
    let device = Device::flex();
    let critic = image_case().critic(&device);
    let mut old = Checkpoint::new();
    write_module(&critic, "c", &mut old);
    for t in old.tensors.values_mut() {
        if t.shape.len() == 5 {
            t.shape.remove(2);
        }
    }
    let read = read_module(image_case().critic(&device), "c", &old).unwrap();
    let x = image_case().input(4, &device);
    let (a, b) = (critic.forward(x.clone()), read.forward(x));
    assert_eq!(
        a.try_into_vec_as::<f32>().unwrap(),
        b.try_into_vec_as::<f32>().unwrap()
    );
}

/// The fused CPU step's loss and gradients equal burn's autodiff of the framework critic's
/// WGAN-GP loss (scores and exact penalty), for every parameter.
fn fused_step_matches_autodiff(case: Case) {
    let device = Device::flex().autodiff();
    let critic = case.critic(&device);
    let (real, fake) = (case.input(2, &device), case.input(3, &device));
    let alphas = vec![0.3f32, 0.8];
    let alpha = Tensor::<1>::from_data(TensorData::new(alphas.clone(), [2]), &device);
    let weights = critic.weights();
    let d_real = critic.score(&weights, real.clone()).mean();
    let d_fake = critic.score(&weights, fake.clone()).mean();
    let penalty = critic.gradient_penalty(&weights, real.clone(), fake.clone(), alpha, 10.0);
    let loss = d_fake.clone() - d_real.clone() + penalty.clone();
    let expected_w = (d_real - d_fake).into_scalar::<f32>();
    let expected_p = penalty.into_scalar::<f32>();
    let grads = loss.backward();

    let host = |t: Tensor<5>| t.try_into_vec_as::<f32>().unwrap();
    let shape = case.shape();
    let fused = fused::FusedCritic::new(&critic, case.channels, [shape[2], shape[3], shape[4]]);
    let step = fused.step(&host(real), &host(fake), &alphas, shape, Some(10.0));
    assert!((step.wasserstein - expected_w).abs() < 1e-4 * expected_w.abs().max(1.0));
    assert!((step.penalty - expected_p).abs() < 1e-4 * expected_p.abs().max(1.0));
    let close = |name: &str, got: &[f32], want: Vec<f32>| {
        let (worst, scale) = crate::testing::assert_gradient_close(name, got, &want);
        eprintln!("{}D {name}: worst {worst:e} of {scale:e}", case.axes);
    };
    for (i, (conv, (w, b))) in critic.convs.iter().zip(&step.convs).enumerate() {
        let gw = conv.weight.val().grad(&grads).unwrap();
        close(
            &format!("conv {i} weight"),
            w,
            gw.try_into_vec_as::<f32>().unwrap(),
        );
        let gb = conv.bias.as_ref().unwrap().val().grad(&grads).unwrap();
        close(
            &format!("conv {i} bias"),
            b,
            gb.try_into_vec_as::<f32>().unwrap(),
        );
    }
    let gh = critic.head.weight.val().grad(&grads).unwrap();
    close(
        "head weight",
        &step.head.0,
        gh.try_into_vec_as::<f32>().unwrap(),
    );
    let ghb = critic
        .head
        .bias
        .as_ref()
        .unwrap()
        .val()
        .grad(&grads)
        .unwrap();
    close(
        "head bias",
        &[step.head.1],
        ghb.try_into_vec_as::<f32>().unwrap(),
    );
}

#[test]
fn fused_step_matches_autodiff_2d() {
    fused_step_matches_autodiff(image_case());
}

#[test]
fn fused_step_matches_autodiff_3d() {
    fused_step_matches_autodiff(volume_case());
}
