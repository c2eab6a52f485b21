//! A radix-2 complex FFT, for the structure measure's autocorrelations.
//!
//! Hand-written rather than a crate's: `rustfft` turns on `num-integer`'s default features,
//! which rebuilds the whole burn chain under them; this is all the measure needs.

/// A complex number.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Complex {
    pub re: f64,
    pub im: f64,
}

impl Complex {
    pub fn norm_sqr(self) -> f64 {
        self.re * self.re + self.im * self.im
    }

    fn mul(self, o: Complex) -> Complex {
        Complex {
            re: self.re * o.re - self.im * o.im,
            im: self.re * o.im + self.im * o.re,
        }
    }
}

/// The discrete Fourier transform of `data` in place (`inverse`: with `e^{+i...}`, unscaled),
/// `X_k = sum_n x_n e^{-2 pi i k n / N}`. The length must be a power of two.
pub fn fft(data: &mut [Complex], inverse: bool) {
    let n = data.len();
    assert!(n.is_power_of_two(), "FFT length {n} is not a power of two");
    // Bit-reversed order, then butterflies of doubling span.
    let bits = n.trailing_zeros();
    for i in 0..n {
        let j = i.reverse_bits() >> (usize::BITS - bits).min(usize::BITS - 1);
        if n > 1 && i < j {
            data.swap(i, j);
        }
    }
    let sign = if inverse { 1.0 } else { -1.0 };
    let mut span = 1;
    while span < n {
        let angle = sign * std::f64::consts::PI / span as f64;
        for start in (0..n).step_by(2 * span) {
            for k in 0..span {
                let (s, c) = (angle * k as f64).sin_cos();
                let t = data[start + k + span].mul(Complex { re: c, im: s });
                let u = data[start + k];
                data[start + k] = Complex {
                    re: u.re + t.re,
                    im: u.im + t.im,
                };
                data[start + k + span] = Complex {
                    re: u.re - t.re,
                    im: u.im - t.im,
                };
            }
        }
        span *= 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_direct_sum_and_inverts() {
        let n = 16;
        let x: Vec<Complex> = (0..n)
            .map(|i| Complex {
                re: ((i * 7) % 5) as f64 - 2.0,
                im: ((i * 3) % 4) as f64 * 0.5,
            })
            .collect();
        let mut y = x.clone();
        fft(&mut y, false);
        for (k, yk) in y.iter().enumerate() {
            let mut d = Complex::default();
            for (i, xi) in x.iter().enumerate() {
                let a = -2.0 * std::f64::consts::PI * (k * i) as f64 / n as f64;
                d.re += xi.re * a.cos() - xi.im * a.sin();
                d.im += xi.re * a.sin() + xi.im * a.cos();
            }
            assert!(
                (d.re - yk.re).abs() < 1e-9 && (d.im - yk.im).abs() < 1e-9,
                "k {k}"
            );
        }
        fft(&mut y, true);
        for (a, b) in x.iter().zip(&y) {
            assert!(
                (a.re - b.re / n as f64).abs() < 1e-12 && (a.im - b.im / n as f64).abs() < 1e-12
            );
        }
        let mut one = vec![Complex { re: 3.0, im: 0.0 }];
        fft(&mut one, false);
        assert_eq!(one[0].re, 3.0);
    }
}
