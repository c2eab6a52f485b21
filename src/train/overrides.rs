//! The command line's training flags: one `--flag` per config key it may override, declared
//! once, with its help and whether a resumed run may change it.

use super::config::TrainConfig;

/// Declares [`TrainOverrides`]: one `--flag` per listed config key, its help, and whether a
/// resumed run may change it. A key is added to the command line here, once.
macro_rules! overrides {
    ($( $(#[doc = $doc:expr])* $key:ident : $ty:ty, $resume:ident $(, $attr:meta)*; )*) => {
        /// Flags that override config keys of the same name (also read from TOML, as a
        /// library caller's settings for a resumed run).
        #[derive(Debug, Clone, Default, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        #[cfg_attr(feature = "cli", derive(clap::Args))]
        pub struct TrainOverrides {
            $(
                $(#[doc = $doc])*
                #[cfg_attr(feature = "cli", arg(long $(, $attr)*))]
                pub $key: Option<$ty>,
            )*
        }

        impl TrainOverrides {
            /// Applies the flags to `config`.
            pub fn apply(&self, config: &mut TrainConfig) {
                $( if let Some(v) = self.$key.clone() { Override::set(&mut config.$key, v); } )*
            }

            /// These flags, and `base`'s where these leave a key unset.
            pub fn over(self, base: Self) -> Self {
                Self { $( $key: self.$key.or(base.$key), )* }
            }

            /// The config keys these flags set.
            pub fn given(&self) -> Vec<&'static str> {
                let mut keys = Vec::new();
                $( if self.$key.is_some() { keys.push(stringify!($key)); } )*
                keys
            }

            /// The flags given that change the model or the random streams, which a resumed run
            /// cannot change.
            pub fn fixed_on_resume(&self) -> Vec<&'static str> {
                let mut fixed = Vec::new();
                $( if self.$key.is_some() && overrides!(@fixed $resume) {
                    fixed.push(concat!("--", stringify!($key)));
                } )*
                fixed
            }
        }
    };
    (@fixed fixed) => { true };
    (@fixed resumable) => { false };
}

/// How a flag's value becomes a config value (`--guide x` sets `Some("x")`).
trait Override<T> {
    fn set(&mut self, value: T);
}

impl<T> Override<T> for T {
    fn set(&mut self, value: T) {
        *self = value;
    }
}

impl Override<String> for Option<String> {
    fn set(&mut self, value: String) {
        *self = Some(value);
    }
}

overrides! {
    /// Total iterations (with --resume: the new total).
    iterations: u64, resumable;
    /// Train for this long, e.g. 15m, 90s or 1h30m: the run plans its iterations from the
    /// speed of its first ones and stops when the budget is spent. Default, when neither --time
    /// nor --iterations (nor a config's `iterations`) is given: 15m, on any device.
    time: String, resumable, value_name = "DURATION";
    /// Crops per step.
    batch: usize, fixed;
    /// Crop size in pixels, a multiple of 16.
    crop: usize, fixed;
    /// Random shift of generated crops, in coordinate units (a crop spans 2).
    shift: f32, fixed;
    /// Critic updates per iteration.
    critic_steps: usize, fixed;
    /// Generator updates per iteration.
    generator_steps: usize, fixed;
    /// Run the gradient penalty on every N-th critic step, weighted N times (lazy
    /// regularisation); 1: every step.
    penalty_every: usize, fixed;
    /// Adam learning rate.
    lr: f64, fixed;
    /// Take the learning rate linearly to 0 over this last fraction of the run, e.g. 0.5; 0:
    /// constant.
    lr_decay: f64, fixed;
    /// K's learning rate as a multiple of --lr, e.g. 10; 1: the same rate as the weights.
    k_lr: f64, fixed;
    /// Weight of the diversity hinge: each generated crop and its twin under a fresh latent
    /// field must differ as much as two crops of the exemplar do; 0: the paper's loss. Default:
    /// 1 for an image with no clear period (the settings printed before training say so), else 0.
    diversity: f64, fixed;
    /// A coarse critic that judges crops painted at every N-th pixel of a crop N times wider,
    /// so it sees several of the pattern's periods; 0 (the default): the fine critic alone.
    coarse_stride: usize, fixed;
    /// Coarse to fine: the first fraction F of the run (e.g. 0.5) trains the one critic on
    /// crops every --coarse-stride-th pixel, the rest on fine crops; 0: no schedule.
    coarse_until: f64, fixed;
    /// Seed of every random draw.
    seed: u64, fixed;
    /// Scale the exemplar first (Lanczos-3, anti-aliased), e.g. 0.5.
    resize: f64, fixed;
    /// Checkpoint every N iterations.
    checkpoint_every: u64, resumable;
    /// Preview image every N iterations.
    preview_every: u64, resumable;
    /// Plain log line every N iterations (when stderr is not a terminal).
    log_every: u64, resumable;
    /// Decay per iteration of the moving average of the generator's weights that is scored,
    /// saved and painted, e.g. 0.99; 0 paints the trained weights.
    average: f64, fixed;
    /// Generator: encoding octaves.
    octaves: usize, fixed;
    /// Generator: latent channels.
    latent_dim: usize, fixed;
    /// Generator: hidden layers.
    hidden_layers: usize, fixed;
    /// Generator: units per hidden layer.
    width: usize, fixed;
    /// Directional guidance (conditional IPFN): x, y, -x, -y or a,b,c, for g = a·x + b·y + c
    /// over the exemplar (x, y in [-1, 1]). The model then needs --guide in synth.
    guide: String, fixed, value_name = "LINE", allow_hyphen_values = true;
    /// Learn a solid texture from the 2D exemplar: a 3D generator whose random axis-aligned
    /// slices must look like the exemplar (paint it with `synth --solid --size WxHxD`).
    solid: bool, fixed, num_args = 0, default_missing_value = "true";
    /// Volumes: density control. Condition the generator and the critic on each crop's
    /// density (mean |sdf|); paint with `synth --density`.
    density: bool, fixed, num_args = 0, default_missing_value = "true";
}
