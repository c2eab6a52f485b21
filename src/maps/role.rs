//! What a map is, from the names material libraries give their files: `color`, `albedo`,
//! `diff`, `basecolor`; `normal`, `nor_gl`, `NormalGL` (and `NormalDX`, `nor_dx`: DirectX's
//! convention); `height`, `disp`, `displacement`; `rough`, `roughness`; `ao`,
//! `AmbientOcclusion`; `metal`, `metalness`.

use serde::{Deserialize, Serialize};

/// A map's part in a material.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MapRole {
    Color,
    Normal,
    Height,
    Roughness,
    AmbientOcclusion,
    Metalness,
}

impl MapRole {
    /// The role a file's stem names (`Bricks075B_1K-PNG_NormalGL`, `red_bricks_04_nor_gl_2k`),
    /// and whether a normal map's name says DirectX (`NormalDX`, `nor_dx`).
    pub fn from_name(stem: &str) -> Option<(Self, bool)> {
        let tokens = tokens(stem);
        let has = |words: &[&str]| tokens.iter().any(|t| words.contains(&t.as_str()));
        let pair = |a: &str, b: &str| tokens.windows(2).any(|w| w[0] == a && w[1] == b);
        let directx = has(&["normaldx", "dx"]);
        let role = if has(&["normal", "normalgl", "normaldx", "nor", "nrm", "norm"]) {
            Self::Normal
        } else if has(&["color", "colour", "albedo", "diff", "diffuse", "basecolor"])
            || pair("base", "color")
        {
            Self::Color
        } else if has(&["height", "disp", "displacement", "bump"]) {
            Self::Height
        } else if has(&["rough", "roughness"]) {
            Self::Roughness
        } else if has(&["ao", "ambientocclusion", "occlusion"]) || pair("ambient", "occlusion") {
            Self::AmbientOcclusion
        } else if has(&["metal", "metalness", "metallic"]) {
            Self::Metalness
        } else {
            return None;
        };
        Some((role, role == Self::Normal && directx))
    }

    /// The role's name: `color`, `normal`, `height`, `roughness`, `ambient_occlusion`,
    /// `metalness`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Color => "color",
            Self::Normal => "normal",
            Self::Height => "height",
            Self::Roughness => "roughness",
            Self::AmbientOcclusion => "ambient_occlusion",
            Self::Metalness => "metalness",
        }
    }
}

/// A name's words, lower case: split at anything not a letter or digit, and where a lower-case
/// letter meets an upper-case one (`NormalGL` is `normal`, `gl`).
fn tokens(name: &str) -> Vec<String> {
    let mut words: Vec<String> = Vec::new();
    let mut word = String::new();
    let mut previous_lower = false;
    for ch in name.chars() {
        if !ch.is_ascii_alphanumeric() {
            words.extend((!word.is_empty()).then(|| std::mem::take(&mut word)));
            previous_lower = false;
            continue;
        }
        if ch.is_ascii_uppercase() && previous_lower {
            words.push(std::mem::take(&mut word));
        }
        previous_lower = ch.is_ascii_lowercase();
        word.push(ch.to_ascii_lowercase());
    }
    words.extend((!word.is_empty()).then_some(word));
    // `NormalGL` splits as `normal`, `gl`; joined again it is one of the names above too.
    let joined: Vec<String> = words
        .windows(2)
        .map(|w| format!("{}{}", w[0], w[1]))
        .collect();
    words.extend(joined);
    words
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roles_come_from_the_names_libraries_give() {
        let cases = [
            ("Bricks075B_1K-PNG_Color", Some((MapRole::Color, false))),
            ("red_bricks_04_diff_2k", Some((MapRole::Color, false))),
            ("albedo", Some((MapRole::Color, false))),
            ("T_Wall_BaseColor", Some((MapRole::Color, false))),
            ("Bricks075B_1K-PNG_NormalGL", Some((MapRole::Normal, false))),
            ("Bricks075B_1K-PNG_NormalDX", Some((MapRole::Normal, true))),
            ("red_bricks_04_nor_gl_2k", Some((MapRole::Normal, false))),
            ("red_bricks_04_nor_dx_2k", Some((MapRole::Normal, true))),
            ("normal", Some((MapRole::Normal, false))),
            (
                "Bark014_1K-JPG_Displacement",
                Some((MapRole::Height, false)),
            ),
            ("rock_disp_4k", Some((MapRole::Height, false))),
            ("height", Some((MapRole::Height, false))),
            ("Ground048_Roughness", Some((MapRole::Roughness, false))),
            ("wood_rough_1k", Some((MapRole::Roughness, false))),
            (
                "Rock029_1K-JPG_AmbientOcclusion",
                Some((MapRole::AmbientOcclusion, false)),
            ),
            ("ao", Some((MapRole::AmbientOcclusion, false))),
            ("Metal012_Metalness", Some((MapRole::Metalness, false))),
            ("preview", None),
            ("red_bricks_04_arm_2k", None),
        ];
        for (name, role) in cases {
            assert_eq!(MapRole::from_name(name), role, "{name}");
        }
    }
}
