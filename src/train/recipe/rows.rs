//! Alternating rows: a running bond, whose joints move by half a brick from one course to the
//! next, repeats unshifted only after two courses. Telling it from a stack bond, and what the
//! recipe sets for it (K on the two courses, held, and a coarse critic over three).

use std::collections::BTreeSet;

use super::{CLEAR_REPEAT, Measured, initial_k};
use crate::exemplar::Exemplar;
use crate::metrics::{Repeat, autocorrelation_at};
use crate::train::TrainConfig;

/// Whether the rows of `window` alternate along `axis`: shifted by one period along it, the
/// pattern is more like itself when also shifted by half the other axis's period than when
/// not (bricks in a running bond, the rows of a honeycomb measured at one row's spacing).
/// Such a pattern repeats unshifted only after two periods.
pub(super) fn staggered(window: &Exemplar, repeat: &[Option<Repeat>; 2], axis: usize) -> bool {
    let clear = |axis: usize| {
        repeat[axis]
            .filter(|r| r.strength >= CLEAR_REPEAT)
            .map(|r| r.period)
    };
    let (Some(along), Some(across)) = (clear(axis), clear(1 - axis)) else {
        return false;
    };
    let shape = [window.height, window.width, window.channels];
    let at = |shift: f64| {
        let (along, shift) = (along.round() as usize, shift.round() as usize);
        let lag = if axis == 0 {
            [along, shift]
        } else {
            [shift, along]
        };
        autocorrelation_at(&window.values, shape, lag)
    };
    at(across / 2.0) > at(0.0)
}

/// How many of its shorter periods a coarse crop spans on an image whose rows alternate: the
/// middle of the two to four that let a critic see the arrangement.
pub const COARSE_PERIODS: f64 = 3.0;

/// For a plain image whose rows alternate (a running bond, [`Measured::staggered`]) and whose
/// fine crop holds less than about [`COARSE_PERIODS`] of its shorter period: the stride at
/// which a coarse crop ([`crate::train::coarse`]) spans about [`COARSE_PERIODS`] periods, to pair with
/// K held on the lattice period ([`initial_k`]), so that the generator can tell one course from
/// the next and a critic sees the joints move from one course to the next.
pub fn alternating_rows(measured: &Measured, config: &TrainConfig) -> Option<usize> {
    if !measured.staggered.contains(&true) {
        return None;
    }
    let period = measured.shortest_period()? * config.resize;
    let side = measured.size[0].min(measured.size[1]) as f64 * config.resize;
    let stride = ((COARSE_PERIODS * period / config.crop as f64).round() as usize)
        .min(crate::train::coarse::largest_stride(
            side as usize,
            config.crop,
        ))
        .min(crate::train::config::MAX_COARSE_STRIDE);
    (stride >= 2).then_some(stride)
}

/// The keys [`apply_alternating_rows`] sets together; a run that sets any of them keeps all three.
const ROW_KEYS: [&str; 3] = ["k_init", "k_lr", "coarse_stride"];

/// Where the rows alternate ([`alternating_rows`]) and the run set none of [`ROW_KEYS`]: K on
/// the lattice period, held, and the coarse critic at [`alternating_rows`]' stride. Without
/// them the generator paints courses whose joints line up or wander; with them, the bond (the
/// book's running-bond experiments). Returns the line that says so.
pub(super) fn apply_alternating_rows(
    measured: &Measured,
    config: &mut TrainConfig,
    explicit: &BTreeSet<String>,
) -> Option<String> {
    if ROW_KEYS.iter().any(|k| explicit.contains(*k)) {
        return None;
    }
    let stride = alternating_rows(measured, config)?;
    let k = initial_k(measured, config.resize, config.crop, config.octaves);
    let line = format!(
        "the rows alternate: K held on two courses (k_init = [{:.3}, {:.3}], k_lr = 0) and a coarse critic on crops of {} px, about {COARSE_PERIODS} periods (--coarse-stride {stride}), so a critic sees the joints move from course to course (half the iterations; setting k_init, k_lr or coarse_stride leaves all three to the run)",
        k[0],
        k[1],
        stride * config.crop,
    );
    config.k_init = Some(k);
    config.k_lr = 0.0;
    config.coarse_stride = stride;
    Some(line)
}

#[cfg(test)]
mod tests {
    use super::super::measure;
    use super::super::tests::measured;
    use super::*;

    #[test]
    fn alternating_rows_double_the_lattice_period() {
        let (side, brick_w, brick_h) = (256, 48, 16);
        // Gray bricks with 2-px white mortar; odd courses shifted by half a brick.
        let running: Vec<f32> = (0..side * side)
            .map(|i| {
                let (y, x) = (i / side, i % side);
                let shift = (y / brick_h % 2) * brick_w / 2;
                let mortar = y % brick_h < 2 || (x + shift) % brick_w < 2;
                if mortar { 1.0 } else { 0.3 }
            })
            .collect();
        let exemplar = |unit: &[f32]| Exemplar::from_unit(side, side, 1, unit);
        let measured = measure(&exemplar(&running));
        assert_eq!(measured.staggered, [true, false], "{measured:?}");
        let down = measured.lattice_period(0).unwrap();
        assert!((down - 2.0 * brick_h as f64).abs() < 1.0, "{measured:?}");
        // The first course repeated: every course's joints in the same place.
        let course = &running[..brick_h * side];
        let stack: Vec<f32> = course.iter().copied().cycle().take(running.len()).collect();
        let measured = measure(&exemplar(&stack));
        assert_eq!(measured.staggered, [false, false], "{measured:?}");
        let down = measured.lattice_period(0).unwrap();
        assert!((down - brick_h as f64).abs() < 1.0, "{measured:?}");
        // The honeycomb's period down already spans two rows of cells.
        let honeycomb = crate::exemplar::read_exemplar(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/exemplars/honeycomb.png"
        )))
        .unwrap();
        assert_eq!(measure(&honeycomb).staggered, [false, false]);
    }

    #[test]
    fn alternating_rows_hold_k_on_two_courses_with_a_coarse_critic_over_three() {
        // brick.jpg as measured: courses 40.1 px, bricks 159.7 px, at the CPU's scale and crop.
        let brick = Measured {
            size: [640, 640],
            staggered: [true, false],
            ..measured([Some(40.1), Some(159.7)])
        };
        let cpu = TrainConfig {
            resize: 0.75,
            crop: 32,
            ..TrainConfig::default()
        };
        assert_eq!(alternating_rows(&brick, &cpu), Some(3));
        let mut config = cpu.clone();
        let line = apply_alternating_rows(&brick, &mut config, &BTreeSet::new()).unwrap();
        assert!(line.contains("crops of 96 px"), "{line}");
        assert!(line.contains("(--coarse-stride 3)"), "{line}");
        let k = initial_k(&brick, 0.75, 32, cpu.octaves);
        let k_init = format!("k_init = [{:.3}, {:.3}]", k[0], k[1]);
        assert!(line.contains(&k_init), "{line}");
        assert!(
            (k[0] - 1.88).abs() < 0.01 && (k[1] - 3.74).abs() < 0.01,
            "{k:?}"
        );
        assert_eq!(
            (config.k_init, config.k_lr, config.coarse_stride),
            (Some(k), 0.0, 3)
        );
        // A run that set any of the three keys keeps all three as they were.
        for key in ROW_KEYS {
            let explicit = BTreeSet::from([key.to_string()]);
            let mut config = cpu.clone();
            assert_eq!(apply_alternating_rows(&brick, &mut config, &explicit), None);
            assert_eq!(config, cpu);
        }
        // Rows that do not alternate, and a crop that already spans about three courses.
        let stack = Measured {
            staggered: [false; 2],
            ..brick.clone()
        };
        assert_eq!(alternating_rows(&stack, &cpu), None);
        let gpu = TrainConfig {
            resize: 1.0,
            crop: 128,
            ..TrainConfig::default()
        };
        assert_eq!(alternating_rows(&brick, &gpu), None);
    }
}
