//! A moving average of the generator's weights (Karras et al. 2018, Yazıcı et al. 2019): the
//! weights a GAN's generator holds at one step swing with the critic; their exponential moving
//! average paints steadier, cleaner samples. When `average` is set, the average is what a run
//! scores, saves as its model (`generator.*` in every file) and previews; the trained weights
//! travel in the training state (`training.generator.*` in `latest.ipfn`), so `--resume`
//! continues both bit for bit.

use crate::generator::GeneratorWeights;

/// Where a training state keeps the trained weights when the model file holds their average.
pub const TRAINED_PREFIX: &str = "training.generator";

/// The decay used at `iteration` (counted from 1): `min(decay, (1 + t) / (10 + t))`, so the
/// first iterations, far from anything worth remembering, are forgotten quickly (TensorFlow's
/// `ExponentialMovingAverage` with `num_updates`).
pub fn decay_at(decay: f64, iteration: u64) -> f32 {
    let t = iteration as f64;
    decay.min((1.0 + t) / (10.0 + t)) as f32
}

/// Moves `average` towards `current`: `average = d * average + (1 - d) * current`, for every
/// weight, bias and K.
pub fn update(average: &mut GeneratorWeights, current: &GeneratorWeights, d: f32) {
    let blend = |a: &mut [f32], c: &[f32]| {
        for (a, &c) in a.iter_mut().zip(c) {
            *a = d * *a + (1.0 - d) * c;
        }
    };
    blend(&mut average.k, &current.k);
    for (a, c) in average.layers.iter_mut().zip(&current.layers) {
        blend(&mut a.weight, &c.weight);
        blend(&mut a.bias, &c.bias);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generator::GeneratorConfig;

    #[test]
    fn the_average_forgets_early_weights_quickly_then_at_the_decay() {
        assert_eq!(decay_at(0.99, 1), 2.0 / 11.0);
        assert_eq!(decay_at(0.99, 10_000), 0.99);
        let config = GeneratorConfig::new().with_hidden_layers(1).with_width(4);
        let zero = {
            let mut w = GeneratorWeights::random(&config, 0);
            w.k.iter_mut().for_each(|k| *k = 0.0);
            w
        };
        let mut one = zero.clone();
        one.k.iter_mut().for_each(|k| *k = 1.0);
        let mut average = zero.clone();
        update(&mut average, &one, 0.75);
        assert_eq!(average.k, vec![0.25, 0.25]);
        // Weights equal in both stay as they are.
        assert_eq!(average.layers, zero.layers);
    }
}
