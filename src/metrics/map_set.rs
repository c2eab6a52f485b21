//! Scores of a map-set model: SIFID reads a picture, so it scores the set's colour map; the
//! structure distance scores every map against that map of the exemplar, since a normal or
//! height map can lose its arrangement while the colour keeps it.

use std::ops::Range;

use super::{Autocorrelation, SampleScores, Samples, Summary, repeat_strength};
use super::{sifid_against, stem_gaussian, structure_floor, structure_lags};
use crate::error::Result;
use crate::exemplar::Exemplar;
use crate::input_error;
use crate::maps::MapSet;

/// How a map-set model's samples score against its exemplar ([`map_set_scores`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MapSetScores {
    /// SIFID, structure and repeat of the colour map ([`MapSet::colour_map`]).
    pub colour: SampleScores,
    /// Each map's structure distance, in the set's order.
    pub structure: Vec<Summary>,
    /// Each map's structure floor (its halves against the whole), in the set's order.
    pub floor: Vec<f64>,
}

/// The channels `range` of every pixel of `values` (`[.., channels]`).
fn pick(values: &[f32], channels: usize, range: &Range<usize>) -> Vec<f32> {
    values
        .chunks_exact(channels)
        .flat_map(|p| p[range.clone()].iter().copied())
        .collect()
}

/// Scores a map-set model's samples against the exemplar (its maps stacked, values in
/// [-1, 1]).
pub fn map_set_scores(
    samples: Samples<'_>,
    exemplar: &Exemplar,
    set: &MapSet,
) -> Result<MapSetScores> {
    let (w, h, c) = (exemplar.width, exemplar.height, exemplar.channels);
    let config = samples.config;
    if c != config.channels || c != set.channels() {
        return Err(input_error!(
            "the exemplar has {c} channels but the model paints {}; evaluate a model with the maps it was trained on",
            config.channels
        ));
    }
    let ranges = set.ranges();
    let colour = set.colour_map();
    let colour_exemplar = exemplar.select(ranges[colour].clone());
    let real = stem_gaussian(&colour_exemplar)?;
    let lags = structure_lags(h, w);
    let maps: Vec<(Vec<f32>, usize)> = ranges
        .iter()
        .map(|r| (pick(&exemplar.values, c, r), r.len()))
        .collect();
    let reals: Vec<Autocorrelation> = maps
        .iter()
        .map(|(v, mc)| Autocorrelation::of(v, h, w, *mc, lags))
        .collect();
    let n = samples.count;
    let (mut sifids, mut repeat) = (Vec::with_capacity(n), [0.0; 2]);
    let mut structures = vec![Vec::with_capacity(n); ranges.len()];
    samples.for_each(exemplar, |sample| {
        for (i, r) in ranges.iter().enumerate() {
            let map = pick(sample, c, r);
            let ac = Autocorrelation::of(&map, h, w, r.len(), lags);
            structures[i].push(reals[i].distance(&ac));
            if i == colour {
                sifids.push(sifid_against(&real, &map, &colour_exemplar)?);
                let s = repeat_strength(&map, h, w, r.len());
                (0..2).for_each(|axis| repeat[axis] += s[axis] / n as f64);
            }
        }
        Ok(())
    })?;
    let structure: Vec<Summary> = structures.into_iter().map(Summary::of).collect();
    Ok(MapSetScores {
        colour: SampleScores {
            sifid: Summary::of(sifids),
            structure: structure[colour].clone(),
            repeat,
        },
        structure,
        floor: maps
            .iter()
            .map(|(v, mc)| structure_floor(v, h, w, *mc))
            .collect(),
    })
}
