//! The classic answer to "make this photo tile", what image editors' "make seamless" filters
//! do: offset the photo by half its size (the seams move to the middle) and cross-fade it with
//! the photo itself, which is kept in the centre and gives way to the offset copy towards the
//! border. The result wraps without a step, at the price of ghosted doubles in between.

use crate::exemplar::Exemplar;

/// The photo cross-faded with itself offset by half: `w I(x) + (1 - w) I(x + P/2)`, with `w`
/// the product of a tent per axis (1 in the centre, 0 at the border).
pub fn crossfade_tile(photo: &Exemplar) -> Exemplar {
    let (h, w, c) = (photo.height, photo.width, photo.channels);
    let tent = |i: usize, n: usize| 1.0 - ((2.0 * (i as f32 + 0.5) / n as f32) - 1.0).abs();
    let mut values = Vec::with_capacity(photo.values.len());
    for y in 0..h {
        for x in 0..w {
            let weight = tent(y, h) * tent(x, w);
            let (sy, sx) = ((y + h / 2) % h, (x + w / 2) % w);
            for ch in 0..c {
                let own = photo.values[(y * w + x) * c + ch];
                let shifted = photo.values[(sy * w + sx) * c + ch];
                values.push(weight * own + (1.0 - weight) * shifted);
            }
        }
    }
    Exemplar {
        values,
        ..photo.clone()
    }
}
