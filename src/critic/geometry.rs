//! A stride-2 convolution's geometry for the fused critic ([`super::fused`]): which input
//! position each tap of an output position reads, and the im2col matrix and its adjoint built
//! from that, on 2 or 3 axes.

use rayon::prelude::*;

/// The most taps a convolution has: 4 per axis on 3 axes.
const MAX_TAPS: usize = 64;

/// One stride-2 convolution's shape over 3 axes (depth, rows, cols); a 2D critic's depth axis
/// has one tap, stride 1 and no padding.
#[derive(Debug, Clone, Copy)]
pub(super) struct Geometry {
    pub(super) inputs: usize,
    pub(super) outputs: usize,
    pub(super) taps: [usize; 3],
    pub(super) stride: [usize; 3],
    pub(super) pad: [usize; 3],
    pub(super) input: [usize; 3],
    pub(super) output: [usize; 3],
}

impl Geometry {
    pub(super) fn in_positions(&self) -> usize {
        self.input.iter().product()
    }

    pub(super) fn out_positions(&self) -> usize {
        self.output.iter().product()
    }

    pub(super) fn tap_count(&self) -> usize {
        self.taps.iter().product()
    }

    /// Columns of the im2col matrix: input channel, then taps (depth, row, col), fastest last,
    /// as the framework's weight `[out, in, taps...]` orders them.
    pub(super) fn patch(&self) -> usize {
        self.tap_count() * self.inputs
    }

    /// The input position a tap of an output position reads, or `None` in the padding.
    fn source(&self, out: [usize; 3], tap: [usize; 3]) -> Option<usize> {
        let mut index = 0;
        for a in 0..3 {
            let i = (out[a] * self.stride[a] + tap[a]).checked_sub(self.pad[a])?;
            if i >= self.input[a] {
                return None;
            }
            index = index * self.input[a] + i;
        }
        Some(index)
    }

    /// Calls `f(tap, input position)` for each tap of output position `p` that reads inside the
    /// input.
    fn for_taps(&self, p: usize, mut f: impl FnMut(usize, usize)) {
        let [_, oh, ow] = self.output;
        let out = [p / (oh * ow), p / ow % oh, p % ow];
        let [td, th, tw] = self.taps;
        for d in 0..td {
            for h in 0..th {
                for w in 0..tw {
                    if let Some(i) = self.source(out, [d, h, w]) {
                        f((d * th + h) * tw + w, i);
                    }
                }
            }
        }
    }

    /// `[patch, in positions, out positions, inputs, taps]`: the sizes im2col and col2im index by.
    fn sizes(&self) -> [usize; 5] {
        [
            self.patch(),
            self.in_positions(),
            self.out_positions(),
            self.inputs,
            self.tap_count(),
        ]
    }

    /// `[batch · out positions, patch]` from channels-last `x` `[batch · in positions, inputs]`.
    /// Each row is written in order, channel by channel, reading its taps' inputs side by side.
    pub(super) fn im2col(&self, x: &[f32], batch: usize) -> Vec<f32> {
        let [patch, pin, pout, c, taps] = self.sizes();
        let len = batch * pout * patch;
        let mut cols = Vec::with_capacity(len);
        cols.spare_capacity_mut()[..len]
            .par_chunks_mut(patch)
            .enumerate()
            .for_each(|(r, row)| {
                let (b, p) = (r / pout, r % pout);
                // Where each tap's inputs start in `x`, or none in the padding.
                let mut sources = [None; MAX_TAPS];
                self.for_taps(p, |tap, i| sources[tap] = Some((b * pin + i) * c));
                for (channel, row) in row.chunks_exact_mut(taps).enumerate() {
                    for (v, source) in row.iter_mut().zip(&sources) {
                        v.write(source.map_or(0.0, |s| x[s + channel]));
                    }
                }
            });
        // SAFETY: every one of the `len` values was written above.
        unsafe { cols.set_len(len) };
        cols
    }

    /// The adjoint of [`Geometry::im2col`]: sums each column back onto the input it was read
    /// from. One sample per task, in a fixed order.
    pub(super) fn col2im(&self, cols: &[f32], batch: usize) -> Vec<f32> {
        let [patch, pin, pout, c, taps] = self.sizes();
        let mut x = vec![0f32; batch * pin * c];
        x.par_chunks_mut(pin * c)
            .enumerate()
            .for_each(|(b, sample)| {
                for p in 0..pout {
                    let row = &cols[(b * pout + p) * patch..][..patch];
                    self.for_taps(p, |tap, i| {
                        for (channel, x) in sample[i * c..(i + 1) * c].iter_mut().enumerate() {
                            *x += row[channel * taps + tap];
                        }
                    });
                }
            });
        x
    }
}
