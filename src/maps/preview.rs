//! A picture of a material rather than of its maps: the painted maps lit as a flat plane seen
//! from above, with one light at a grazing angle, so the relief of the normal (or height) map
//! and the sheen of the roughness map show. The shading is Cook-Torrance with a GGX
//! distribution, Smith-Schlick masking and Schlick's Fresnel (as glTF and most real-time
//! engines shade), plus an ambient term darkened by the ambient-occlusion map.

use std::path::Path;

use super::{MapRole, MapSet};
use crate::error::Result;

/// The light's elevation above the plane: low, so that relief casts visible shading.
const LIGHT_ELEVATION_DEG: f32 = 30.0;
/// The light's intensity and the ambient light's, in linear units.
const LIGHT: f32 = 3.0;
const AMBIENT: f32 = 0.12;
/// How steep a height map's relief is drawn where the set has no normal map (per pixel).
const HEIGHT_RELIEF: f32 = 4.0;
/// The largest preview side: a bigger painting is previewed by its top-left corner.
pub const MAX_PREVIEW_SIDE: usize = 1024;

/// Where each role's channels start in the stacked pixel, as a set's maps say.
struct Layout {
    color: Option<usize>,
    normal: Option<usize>,
    height: Option<usize>,
    roughness: Option<usize>,
    ao: Option<usize>,
    metalness: Option<usize>,
}

impl Layout {
    fn of(set: &MapSet) -> Self {
        let mut layout = Layout {
            color: None,
            normal: None,
            height: None,
            roughness: None,
            ao: None,
            metalness: None,
        };
        for (map, range) in set.maps.iter().zip(set.ranges()) {
            // A map of no known name: a normal map is one; a first colour image is the colour.
            let role = map.role.or(if map.normal {
                Some(MapRole::Normal)
            } else if map.channels >= 3 && layout.color.is_none() {
                Some(MapRole::Color)
            } else {
                None
            });
            let slot = match role {
                Some(MapRole::Color) if map.channels >= 3 => &mut layout.color,
                Some(MapRole::Normal) if map.channels >= 3 => &mut layout.normal,
                Some(MapRole::Height) => &mut layout.height,
                Some(MapRole::Roughness) => &mut layout.roughness,
                Some(MapRole::AmbientOcclusion) => &mut layout.ao,
                Some(MapRole::Metalness) => &mut layout.metalness,
                _ => continue,
            };
            slot.get_or_insert(range.start);
        }
        layout
    }
}

/// The material of `set` lit, from the stacked painting `values` (`[height, width, channels]`,
/// in [-1, 1], normals in OpenGL's convention as the model paints them).
///
/// # Shapes
/// - values: `[height, width, set.channels()]`
/// - output: `[height, width, 3]`, in [-1, 1] (sRGB-encoded, as image files hold colour)
pub fn render(set: &MapSet, values: &[f32], [height, width]: [usize; 2]) -> Vec<f32> {
    let c = set.channels();
    let layout = Layout::of(set);
    let at = |x: usize, y: usize, k: usize| values[(y * width + x) * c + k];
    let unit = |v: f32| ((v + 1.0) * 0.5).clamp(0.0, 1.0);
    let elevation = LIGHT_ELEVATION_DEG.to_radians();
    // From the upper left, as painters light; image rows run down, the tangent's y up.
    let (ce, se) = (elevation.cos(), elevation.sin());
    let light = normalize([
        -ce * std::f32::consts::FRAC_1_SQRT_2,
        ce * std::f32::consts::FRAC_1_SQRT_2,
        se,
    ]);
    let mut out = Vec::with_capacity(height * width * 3);
    for y in 0..height {
        for x in 0..width {
            let normal = match (layout.normal, layout.height) {
                (Some(k), _) => normalize([at(x, y, k), at(x, y, k + 1), at(x, y, k + 2)]),
                (None, Some(k)) => {
                    let dx = at((x + 1).min(width - 1), y, k) - at(x.saturating_sub(1), y, k);
                    let dy = at(x, (y + 1).min(height - 1), k) - at(x, y.saturating_sub(1), k);
                    // Rows run down: a height rising down the image tilts the normal up (+y).
                    normalize([-dx * HEIGHT_RELIEF * 0.5, dy * HEIGHT_RELIEF * 0.5, 1.0])
                }
                (None, None) => [0.0, 0.0, 1.0],
            };
            let base = match layout.color {
                Some(k) => [0, 1, 2].map(|i| srgb_to_linear(unit(at(x, y, k + i)))),
                None => [0.5; 3],
            };
            let shade = Surface {
                normal,
                base,
                roughness: layout.roughness.map_or(0.6, |k| unit(at(x, y, k))),
                metalness: layout.metalness.map_or(0.0, |k| unit(at(x, y, k))),
                ao: layout.ao.map_or(1.0, |k| unit(at(x, y, k))),
            }
            .shade(light);
            out.extend(shade.map(|v| linear_to_srgb(v) * 2.0 - 1.0));
        }
    }
    out
}

/// Writes the preview of `set` from its stacked painting as an 8-bit PNG, atomically.
pub fn write(path: &Path, set: &MapSet, values: &[f32], size: [usize; 2]) -> Result<()> {
    let rgb = render(set, values, size);
    crate::io::write_png(path, size[1], size[0], 3, &rgb)
}

/// `--preview PATH`: a preview is written as a PNG.
pub fn check_path(path: &Path) -> Result<()> {
    let png = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if png {
        Ok(())
    } else {
        Err(crate::setting_error!(
            "--preview",
            path.display(),
            "a preview is a picture; give a .png"
        ))
    }
}

/// The painted region a preview of a `size` painting shows: the whole, up to
/// [`MAX_PREVIEW_SIDE`] a side.
pub fn region([height, width]: [usize; 2]) -> [usize; 2] {
    [height.min(MAX_PREVIEW_SIDE), width.min(MAX_PREVIEW_SIDE)]
}

/// One pixel's material.
struct Surface {
    normal: [f32; 3],
    /// Linear base colour.
    base: [f32; 3],
    roughness: f32,
    metalness: f32,
    ao: f32,
}

impl Surface {
    /// Linear radiance towards a viewer straight above, under a light from `light`.
    fn shade(&self, light: [f32; 3]) -> [f32; 3] {
        let n = self.normal;
        let view = [0.0, 0.0, 1.0];
        let half = normalize([light[0] + view[0], light[1] + view[1], light[2] + view[2]]);
        let (nl, nv) = (dot(n, light).max(0.0), dot(n, view).max(1e-4));
        let (nh, vh) = (dot(n, half).max(0.0), dot(view, half).max(0.0));
        let alpha = (self.roughness * self.roughness).max(1e-3);
        let a2 = alpha * alpha;
        let d = a2 / (std::f32::consts::PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
        let k = alpha / 2.0;
        let g = (nl / (nl * (1.0 - k) + k)) * (nv / (nv * (1.0 - k) + k));
        let m = self.metalness;
        [0, 1, 2].map(|i| {
            let f0 = 0.04 * (1.0 - m) + self.base[i] * m;
            let f = f0 + (1.0 - f0) * (1.0 - vh).powi(5);
            let specular = d * g * f / (4.0 * nl.max(1e-4) * nv);
            let diffuse = (1.0 - f) * (1.0 - m) * self.base[i] / std::f32::consts::PI;
            (diffuse + specular) * LIGHT * nl + AMBIENT * self.base[i] * self.ao
        })
    }
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let len = dot(v, v).sqrt();
    if len > 1e-12 {
        v.map(|x| x / len)
    } else {
        [0.0, 0.0, 1.0]
    }
}

fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::maps::MapInfo;

    fn map(name: &str, channels: usize, role: MapRole) -> MapInfo {
        MapInfo {
            name: name.into(),
            channels,
            bits: 8,
            normal: role == MapRole::Normal,
            role: Some(role),
            directx: false,
            stored_channels: None,
        }
    }

    /// A colour map and a normal map, two pixels side by side: `normals` one per pixel.
    fn lit(normals: [[f32; 3]; 2], rough: f32) -> Vec<f32> {
        let set = MapSet {
            maps: vec![
                map("color", 3, MapRole::Color),
                map("normal", 3, MapRole::Normal),
                map("rough", 1, MapRole::Roughness),
            ],
        };
        let values: Vec<f32> = normals
            .iter()
            .flat_map(|n| [0.2, 0.2, 0.2, n[0], n[1], n[2], rough])
            .collect();
        render(&set, &values, [1, 2])
    }

    #[test]
    fn a_face_turned_to_the_light_is_brighter_than_one_turned_away() {
        // The light comes from the upper left: -x, +y.
        let out = lit([[-0.5, 0.5, 0.7], [0.5, -0.5, 0.7]], 0.0);
        assert!(out[0] > out[3] + 0.2, "{out:?}");
        // A gray material stays gray.
        assert!((out[0] - out[1]).abs() < 1e-6 && (out[1] - out[2]).abs() < 1e-6);
    }

    #[test]
    fn a_flat_uniform_material_is_uniform_and_within_range() {
        let out = lit([[0.0, 0.0, 1.0]; 2], 0.4);
        assert_eq!(out.len(), 6);
        assert_eq!(out[..3], out[3..]);
        assert!(out.iter().all(|v| (-1.0..=1.0).contains(v)));
    }

    #[test]
    fn a_smooth_surface_shines_where_a_rough_one_does_not() {
        // Facing the half vector between the light and the viewer: the highlight.
        let e = LIGHT_ELEVATION_DEG.to_radians();
        let half = normalize([
            -e.cos() * std::f32::consts::FRAC_1_SQRT_2,
            e.cos() * std::f32::consts::FRAC_1_SQRT_2,
            e.sin() + 1.0,
        ]);
        let smooth = lit([half; 2], -0.8)[0];
        let rough = lit([half; 2], 1.0)[0];
        assert!(smooth > rough + 0.2, "smooth {smooth}, rough {rough}");
    }

    #[test]
    fn a_set_without_normals_takes_its_relief_from_the_height_map() {
        let set = MapSet {
            maps: vec![
                map("color", 3, MapRole::Color),
                map("height", 1, MapRole::Height),
            ],
        };
        // Height rising to the right: the surface faces left, towards the light.
        let rising: Vec<f32> = (0..3)
            .flat_map(|x| [0.0, 0.0, 0.0, x as f32 * 0.5 - 0.5])
            .collect();
        let falling: Vec<f32> = (0..3)
            .flat_map(|x| [0.0, 0.0, 0.0, 0.5 - x as f32 * 0.5])
            .collect();
        let (a, b) = (
            render(&set, &rising, [1, 3]),
            render(&set, &falling, [1, 3]),
        );
        assert!(a[3] > b[3] + 0.1, "rising {a:?}, falling {b:?}");
    }

    #[test]
    fn previews_are_capped_to_a_corner() {
        assert_eq!(region([300, 200]), [300, 200]);
        assert_eq!(region([4096, 500]), [MAX_PREVIEW_SIDE, 500]);
    }
}
