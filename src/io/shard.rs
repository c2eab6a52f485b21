//! Splitting a render among workers: `--shard K/N`, or the index a batch engine (a Kubernetes
//! Indexed Job, a SLURM job array) gives each worker in its environment.

use std::str::FromStr;

use crate::error::Result;
use crate::input_error;

/// Which chunks a worker renders: the `index`-th of `count` disjoint sets (chunk `n`, counted in
/// C order over the chunk grid, belongs to shard `n % count`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// The whole array, one worker.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    pub fn new(index: usize, count: usize) -> Result<Self> {
        if count == 0 {
            return Err(input_error!(
                "shard {index}/{count}: the shard count must be at least 1"
            ));
        }
        if index >= count {
            return Err(input_error!(
                "shard {index}/{count}: shards are numbered from 0 to {} (K/N with K < N)",
                count - 1
            ));
        }
        Ok(Self { index, count })
    }

    /// Whether chunk number `n` (C order over the chunk grid) is this shard's.
    pub fn owns(&self, n: usize) -> bool {
        n % self.count == self.index
    }

    /// The shard from a batch engine's environment, read through `env`:
    /// - the index from `var` when given, else `JOB_COMPLETION_INDEX` (a Kubernetes Indexed
    ///   Job), else `SLURM_ARRAY_TASK_ID` less `SLURM_ARRAY_TASK_MIN`, over
    ///   `SLURM_ARRAY_TASK_STEP` (a SLURM job array: `--array=1-8` and `--array=0-28:4` work as
    ///   well as `0-7`);
    /// - the count from `count`, else `SLURM_ARRAY_TASK_COUNT`.
    pub fn from_env(
        var: Option<&str>,
        count: Option<usize>,
        env: impl Fn(&str) -> Option<String>,
    ) -> Result<Self> {
        let number = |name: &str, value: String| {
            value.trim().parse::<usize>().map_err(|_| {
                input_error!(
                    "--shard-from-env: {name}={value:?} is not a shard number (0, 1, 2, ...)"
                )
            })
        };
        let index = match var {
            Some(name) => {
                let value = env(name).ok_or_else(|| {
                    crate::setting_error!(
                        "--shard-from-env",
                        name,
                        "the variable {name} is not set"
                    )
                })?;
                number(name, value)?
            }
            None => match (env("JOB_COMPLETION_INDEX"), env("SLURM_ARRAY_TASK_ID")) {
                (Some(v), _) => number("JOB_COMPLETION_INDEX", v)?,
                (None, Some(v)) => {
                    let id = number("SLURM_ARRAY_TASK_ID", v)?;
                    let min = match env("SLURM_ARRAY_TASK_MIN") {
                        Some(m) => number("SLURM_ARRAY_TASK_MIN", m)?,
                        None => 0,
                    };
                    let step = match env("SLURM_ARRAY_TASK_STEP") {
                        Some(s) => number("SLURM_ARRAY_TASK_STEP", s)?.max(1),
                        None => 1,
                    };
                    id.checked_sub(min).ok_or_else(|| {
                        input_error!("--shard-from-env: SLURM_ARRAY_TASK_ID {id} is below SLURM_ARRAY_TASK_MIN {min}")
                    })? / step
                }
                (None, None) => {
                    return Err(input_error!(
                        "--shard-from-env: neither JOB_COMPLETION_INDEX (Kubernetes) nor SLURM_ARRAY_TASK_ID (SLURM) is set; name the variable, e.g. --shard-from-env TASK_INDEX"
                    ));
                }
            },
        };
        let count = match (count, env("SLURM_ARRAY_TASK_COUNT")) {
            (Some(n), _) => n,
            (None, Some(n)) => number("SLURM_ARRAY_TASK_COUNT", n)?,
            (None, None) => {
                return Err(input_error!(
                    "--shard-from-env: give the number of shards with --shards N"
                ));
            }
        };
        Self::new(index, count)
    }
}

impl FromStr for Shard {
    type Err = String;

    /// `K/N`, e.g. `0/4` to `3/4`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let err = || format!("'{s}': expected K/N with 0 <= K < N, e.g. 0/4");
        let (k, n) = s.split_once('/').ok_or_else(err)?;
        let k: usize = k.trim().parse().map_err(|_| err())?;
        let n: usize = n.trim().parse().map_err(|_| err())?;
        Shard::new(k, n).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let pairs: Vec<(String, String)> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |name| {
            pairs
                .iter()
                .find(|(k, _)| k == name)
                .map(|(_, v)| v.clone())
        }
    }

    #[test]
    fn shard_parses_and_checks() {
        assert_eq!(
            "2/7".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 7 }
        );
        assert!("7/7".parse::<Shard>().is_err());
        assert!("0/0".parse::<Shard>().is_err());
        assert!("a/3".parse::<Shard>().is_err());
        let s = Shard::new(1, 3).unwrap();
        let owned: Vec<usize> = (0..9).filter(|&n| s.owns(n)).collect();
        assert_eq!(owned, vec![1, 4, 7]);
    }

    #[test]
    fn shard_from_each_engine() {
        let k8s = Shard::from_env(None, Some(4), env(&[("JOB_COMPLETION_INDEX", "3")])).unwrap();
        assert_eq!(k8s, Shard { index: 3, count: 4 });
        let slurm = env(&[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
        ]);
        assert_eq!(
            Shard::from_env(None, None, slurm).unwrap(),
            Shard { index: 4, count: 8 }
        );
        let stepped = env(&[
            ("SLURM_ARRAY_TASK_ID", "28"),
            ("SLURM_ARRAY_TASK_STEP", "4"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
        ]);
        assert_eq!(
            Shard::from_env(None, None, stepped).unwrap(),
            Shard { index: 7, count: 8 }
        );
        let named = Shard::from_env(Some("I"), Some(2), env(&[("I", "1")])).unwrap();
        assert_eq!(named, Shard { index: 1, count: 2 });
        assert!(Shard::from_env(None, Some(2), env(&[])).is_err());
        assert!(Shard::from_env(Some("I"), Some(2), env(&[("I", "x")])).is_err());
        assert!(Shard::from_env(None, None, env(&[("JOB_COMPLETION_INDEX", "0")])).is_err());
        assert!(Shard::from_env(Some("I"), Some(2), env(&[("I", "2")])).is_err());
    }
}
