//! Helpers shared by unit tests.

/// Asserts that `got` equals `want` (a gradient from burn's autodiff) to `1e-4` of `want`'s
/// largest entry; returns the worst difference and that scale.
pub fn assert_gradient_close(name: &str, got: &[f32], want: &[f32]) -> (f32, f32) {
    let scale = want.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-6);
    let worst = got
        .iter()
        .zip(want)
        .fold(0f32, |m, (g, w)| m.max((g - w).abs()));
    assert_eq!(got.len(), want.len(), "{name}: length");
    assert!(
        worst < 1e-4 * scale,
        "{name}: differs from autodiff by {worst} (scale {scale})"
    );
    (worst, scale)
}
