//! The periodic network's derivatives: tangents against finite differences, the loss's weight
//! gradient (burn autodiff) against finite differences, and the fused CPU backward against
//! autodiff.

use burn::prelude::*;

use super::fused::{Batch, Stage};
use super::network::{NetworkShape, PeriodicNet, StageShape, half_band};
use super::reference;
use super::target::OwnedBatch;

/// A small stage: 12 frequencies up to 3 cycles over a 20x16 period, two hidden layers.
fn small_net(omega0: f32) -> PeriodicNet {
    let shape = NetworkShape {
        period: [20, 16],
        channels: 2,
        omega0,
        stages: vec![StageShape {
            frequencies: half_band(0, 3, 12, 5),
            hidden: vec![10, 8],
        }],
    };
    PeriodicNet::init(shape, 9)
}

fn stage(net: &PeriodicNet) -> Stage<'_> {
    let s = &net.shape;
    Stage::new(&s.stages[0], &net.params[0], s.channels, s.omega0, s.period)
}

/// 300 points; the first 120 weigh in the gradient term, all weigh in the value term.
fn batch() -> OwnedBatch {
    let mut b = OwnedBatch::default();
    for i in 0..300u64 {
        let r =
            |k: u64| (crate::latent::derive_seed(77, &[i, k]) >> 40) as f32 / (1u64 << 24) as f32;
        b.positions.extend([r(0) * 20.0, r(1) * 16.0]);
        b.values.extend([r(2) - 0.5, r(3) - 0.5]);
        b.gradients.extend([
            r(4) * 0.2 - 0.1,
            r(5) * 0.2 - 0.1,
            r(6) * 0.2 - 0.1,
            r(7) * 0.2 - 0.1,
        ]);
        let l = if i < 120 { r(8) } else { 0.0 };
        b.value_weight.push(1.0 - l);
        b.gradient_weight.push(l);
    }
    b
}

fn relative(a: &[f32], b: &[f32]) -> f64 {
    let diff: f64 = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum();
    let norm: f64 = b.iter().map(|y| (*y as f64).powi(2)).sum();
    (diff / norm.max(1e-30)).sqrt()
}

#[test]
fn tangents_match_finite_differences() {
    let net = small_net(30.0);
    let stage = stage(&net);
    let b = batch();
    let n = b.positions.len() / 2;
    let c = 2;
    let (mut values, mut tangents) = (vec![0f32; n * c], vec![0f32; n * 2 * c]);
    stage.eval(&b.positions, &mut values, Some(&mut tangents));
    let h = 1e-2f32;
    let mut numeric = vec![0f32; n * 2 * c];
    for d in 0..2 {
        let moved = |sign: f32| -> Vec<f32> {
            let mut p = b.positions.clone();
            p.iter_mut().skip(d).step_by(2).for_each(|v| *v += sign * h);
            let mut v = vec![0f32; n * c];
            stage.eval(&p, &mut v, None);
            v
        };
        let (plus, minus) = (moved(1.0), moved(-1.0));
        for i in 0..n {
            for ch in 0..c {
                numeric[(i * 2 + d) * c + ch] = (plus[i * c + ch] - minus[i * c + ch]) / (2.0 * h);
            }
        }
    }
    let err = relative(&tangents, &numeric);
    assert!(
        err < 2e-3,
        "tangents differ from finite differences by {err} (relative)"
    );
    // The burn forward computes the same tangents.
    let (v, t) = reference::eval(&stage, &b.positions, &Device::flex());
    assert!(relative(&v, &values) < 1e-5 && relative(&t, &tangents) < 1e-5);
}

#[test]
fn autodiff_weight_gradient_matches_finite_differences() {
    let net = small_net(30.0);
    let b = batch();
    let view: Batch = b.view();
    let (_, grad) = reference::loss_and_gradient(&stage(&net), &view, &Device::flex());
    // Central differences of the loss, in f64 sums of f32 evaluations, on every 7th parameter.
    let loss_at = |params: &[f32]| {
        let mut moved = net.clone();
        moved.params[0] = params.to_vec();
        stage(&moved).loss_and_gradient(&view).0
    };
    let (mut analytic, mut numeric) = (Vec::new(), Vec::new());
    for i in (0..net.params[0].len()).step_by(7) {
        let h = 1e-3f32;
        let mut p = net.params[0].clone();
        p[i] += h;
        let plus = loss_at(&p);
        p[i] -= 2.0 * h;
        let minus = loss_at(&p);
        analytic.push(grad[i]);
        numeric.push(((plus - minus) / (2.0 * h as f64)) as f32);
    }
    let err = relative(&analytic, &numeric);
    assert!(
        err < 1e-2,
        "d(loss)/dW differs from finite differences by {err} (relative)"
    );
}

#[test]
fn fused_backward_matches_autodiff() {
    let net = small_net(30.0);
    let b = batch();
    let (loss, fused) = stage(&net).loss_and_gradient(&b.view());
    let (reference_loss, autodiff) =
        reference::loss_and_gradient(&stage(&net), &b.view(), &Device::flex());
    assert!((loss - reference_loss).abs() <= 1e-4 * reference_loss.abs());
    let err = relative(&fused, &autodiff);
    assert!(
        err < 1e-4,
        "fused gradient differs from autodiff by {err} (relative)"
    );
}

#[test]
fn the_network_is_exactly_periodic() {
    let net = small_net(30.0);
    let stage = stage(&net);
    let p = [3.25f32, 7.5, 3.25 + 20.0, 7.5 + 16.0 * 3.0];
    let mut v = vec![0f32; 4];
    stage.eval(&p, &mut v, None);
    assert!(
        (v[0] - v[2]).abs() < 1e-4 && (v[1] - v[3]).abs() < 1e-4,
        "{v:?}"
    );
}
