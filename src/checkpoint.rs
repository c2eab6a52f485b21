//! Checkpoint files (`.ipfn`): one safetensors file holding the model's config (JSON in the
//! header metadata), a format tag and version, and named float32 tensors.
//!
//! Later, training state (critic, optimiser moments, RNG counters) goes into the same file under
//! its own tensor names and metadata keys. Files are written atomically.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::io::write_atomic;

/// Metadata key whose value identifies an ipfn checkpoint.
pub const FORMAT_KEY: &str = "format";
/// Value of [`FORMAT_KEY`].
pub const FORMAT_NAME: &str = "ipfn-checkpoint";
/// Metadata key of the format version.
pub const VERSION_KEY: &str = "format_version";
/// The version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// A float32 tensor: row-major values and their shape.
#[derive(Debug, Clone, PartialEq)]
pub struct Tensor32 {
    pub shape: Vec<usize>,
    pub values: Vec<f32>,
}

/// The contents of a checkpoint file.
#[derive(Debug, Clone, Default)]
pub struct Checkpoint {
    /// Where it was read from (for error messages); empty for a new checkpoint.
    pub source: PathBuf,
    pub metadata: BTreeMap<String, String>,
    pub tensors: BTreeMap<String, Tensor32>,
}

impl Checkpoint {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn insert(&mut self, name: impl Into<String>, shape: Vec<usize>, values: Vec<f32>) {
        assert_eq!(
            shape.iter().product::<usize>(),
            values.len(),
            "tensor shape and data disagree"
        );
        self.tensors.insert(name.into(), Tensor32 { shape, values });
    }

    /// The tensor `name`, which must have `shape` (up to axes of size 1: a 2D critic's weights
    /// were stored without the depth axis they now have); an error names the file otherwise.
    pub fn tensor(&self, name: &str, shape: &[usize]) -> Result<&[f32]> {
        let t = self.tensors.get(name).ok_or_else(|| {
            crate::file_error!(
                &self.source,
                "tensor {name} is missing: the file is not a model of this kind",
            )
        })?;
        let squeezed = |s: &[usize]| s.iter().copied().filter(|&n| n != 1).collect::<Vec<_>>();
        let lacks_unit_axes = t.shape.len() < shape.len() && squeezed(&t.shape) == squeezed(shape);
        if t.shape != shape && !lacks_unit_axes {
            return Err(crate::file_error!(
                &self.source,
                "tensor {name} has shape {:?}, expected {:?}: the checkpoint is for another model shape",
                t.shape,
                shape,
            ));
        }
        Ok(&t.values)
    }

    /// A metadata value that must be present.
    pub fn meta(&self, key: &str) -> Result<&str> {
        self.metadata.get(key).map(String::as_str).ok_or_else(|| {
            crate::file_error!(
                &self.source,
                "checkpoint has no '{key}' entry: the file is damaged or not an ipfn model",
            )
        })
    }

    /// Serialises to safetensors bytes, adding the format tag and version.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut metadata: HashMap<String, String> = self.metadata.clone().into_iter().collect();
        metadata.insert(FORMAT_KEY.into(), FORMAT_NAME.into());
        metadata.insert(VERSION_KEY.into(), FORMAT_VERSION.to_string());
        let bytes: Vec<(String, Vec<u8>, Vec<usize>)> = self
            .tensors
            .iter()
            .map(|(name, t)| {
                (
                    name.clone(),
                    t.values.iter().flat_map(|v| v.to_le_bytes()).collect(),
                    t.shape.clone(),
                )
            })
            .collect();
        let views: Vec<(String, safetensors::tensor::TensorView<'_>)> = bytes
            .iter()
            .map(|(name, data, shape)| {
                let view = safetensors::tensor::TensorView::new(
                    safetensors::Dtype::F32,
                    shape.clone(),
                    data,
                )
                .expect("tensor byte length matches its shape");
                (name.clone(), view)
            })
            .collect();
        safetensors::serialize(views, Some(metadata))
            .expect("checkpoint header fits safetensors' limits")
    }

    /// Writes the checkpoint to `path` atomically (temporary file, then rename).
    pub fn save(&self, path: &Path) -> Result<()> {
        write_atomic(path, &self.to_bytes())
    }

    /// Reads and validates a checkpoint file.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => crate::file_error!(&path, "no such model file"),
            _ => crate::file_error!(&path, "cannot read model: {e}"),
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// Parses checkpoint bytes; `path` names the source in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self> {
        let not_ours = || {
            crate::file_error!(
                &path,
                "not an ipfn model (to convert an authors' PyTorch generator, run `ipfn import {} -o model.ipfn`)",
                path.display(),
            )
        };
        let (_, header) = safetensors::SafeTensors::read_metadata(bytes).map_err(|_| {
            if path.extension().is_some_and(|e| e == "ipfn") {
                crate::file_error!(&path, "corrupt model file (truncated or damaged)",)
            } else {
                not_ours()
            }
        })?;
        let metadata: BTreeMap<String, String> = header
            .metadata()
            .clone()
            .unwrap_or_default()
            .into_iter()
            .collect();
        if metadata.get(FORMAT_KEY).map(String::as_str) != Some(FORMAT_NAME) {
            return Err(not_ours());
        }
        let version: u32 = metadata
            .get(VERSION_KEY)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| {
                crate::file_error!(&path, "checkpoint has no readable format version",)
            })?;
        if version != FORMAT_VERSION {
            return Err(crate::file_error!(
                &path,
                "checkpoint format version {version}, this ipfn reads version {FORMAT_VERSION}",
            ));
        }
        let st = safetensors::SafeTensors::deserialize(bytes)
            .map_err(|e| crate::file_error!(&path, "corrupt model file: {e}"))?;
        let mut tensors = BTreeMap::new();
        for (name, view) in st.tensors() {
            if view.dtype() != safetensors::Dtype::F32 {
                return Err(crate::file_error!(
                    &path,
                    "tensor {name} is {:?}, expected F32",
                    view.dtype(),
                ));
            }
            let values = view
                .data()
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
            tensors.insert(
                name,
                Tensor32 {
                    shape: view.shape().to_vec(),
                    values,
                },
            );
        }
        Ok(Self {
            source: path.to_path_buf(),
            metadata,
            tensors,
        })
    }
}

/// Stores every float parameter of `module` as `{prefix}.{path}` (e.g. `critic.convs.0.weight`).
pub fn write_module<M: burn::module::Module>(
    module: &M,
    prefix: &str,
    checkpoint: &mut Checkpoint,
) {
    struct Collect<'a> {
        path: Vec<String>,
        prefix: &'a str,
        out: &'a mut Checkpoint,
    }
    impl burn::module::ModuleVisitor for Collect<'_> {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.path.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.path.pop();
        }
        fn visit_float<const D: usize>(
            &mut self,
            param: &burn::module::Param<burn::tensor::Tensor<D>>,
        ) {
            let tensor = param.val();
            let shape = tensor.dims().to_vec();
            let values = tensor
                .try_into_vec_as::<f32>()
                .expect("parameters are readable as f32");
            let name = format!("{}.{}", self.prefix, self.path.join("."));
            assert!(
                !self.out.tensors.contains_key(&name),
                "duplicate parameter path {name}"
            );
            self.out.insert(name, shape, values);
        }
    }
    module.visit(&mut Collect {
        path: Vec::new(),
        prefix,
        out: checkpoint,
    });
}

/// A change to each float parameter of a module, told the parameter's path (`layers.0.weight`),
/// which names it in a checkpoint and in an optimiser's state ([`map_by_path`]).
pub trait MapByPath {
    fn map<const D: usize>(
        &mut self,
        path: &str,
        id: burn::module::ParamId,
        tensor: burn::tensor::Tensor<D>,
    ) -> burn::tensor::Tensor<D>;
}

/// Applies `f` to every float parameter of `module`, keeping parameter identities and
/// restoring `require_grad` on the parameters that had it.
pub fn map_by_path<M: burn::module::Module, F: MapByPath>(module: M, f: &mut F) -> M {
    use burn::module::Param;
    use burn::tensor::Tensor;
    struct Walk<'a, F> {
        path: Vec<String>,
        f: &'a mut F,
    }
    impl<F: MapByPath> burn::module::ModuleMapper for Walk<'_, F> {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.path.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.path.pop();
        }
        fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            let (id, tensor, mapper) = param.consume();
            let require_grad = tensor.is_require_grad();
            let mapped = self.f.map(&self.path.join("."), id, tensor);
            let mapped = match require_grad && !mapped.is_require_grad() {
                true => mapped.require_grad(),
                false => mapped,
            };
            Param::from_mapped_value(id, mapped, mapper)
        }
    }
    module.map(&mut Walk {
        path: Vec::new(),
        f,
    })
}

/// Replaces every float parameter of `module` by `{prefix}.{path}` from `checkpoint`, keeping
/// parameter identities and whether they require gradients.
pub fn read_module<M: burn::module::Module>(
    module: M,
    prefix: &str,
    checkpoint: &Checkpoint,
) -> Result<M> {
    use burn::tensor::{Tensor, TensorData};
    struct Load<'a> {
        prefix: &'a str,
        checkpoint: &'a Checkpoint,
        error: Option<crate::Error>,
    }
    impl MapByPath for Load<'_> {
        fn map<const D: usize>(
            &mut self,
            path: &str,
            _: burn::module::ParamId,
            tensor: Tensor<D>,
        ) -> Tensor<D> {
            let shape = tensor.dims();
            match self
                .checkpoint
                .tensor(&format!("{}.{path}", self.prefix), &shape)
            {
                Ok(values) => Tensor::<D>::from_data(
                    TensorData::new(values.to_vec(), shape),
                    &tensor.device(),
                ),
                Err(e) => {
                    self.error.get_or_insert(e);
                    tensor
                }
            }
        }
    }
    let mut load = Load {
        prefix,
        checkpoint,
        error: None,
    };
    let module = map_by_path(module, &mut load);
    match load.error {
        Some(e) => Err(e),
        None => Ok(module),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_corruption() {
        let mut c = Checkpoint::new();
        c.metadata.insert("config".into(), "{}".into());
        c.insert("a", vec![2, 3], (0..6).map(|v| v as f32).collect());
        let bytes = c.to_bytes();
        let back = Checkpoint::from_bytes(&bytes, Path::new("m.ipfn")).unwrap();
        assert_eq!(back.tensors, c.tensors);
        assert_eq!(back.tensor("a", &[2, 3]).unwrap()[5], 5.0);
        let err = back.tensor("a", &[3, 2]).unwrap_err().to_string();
        assert!(
            err.contains("m.ipfn") && err.contains("another model shape"),
            "{err}"
        );

        let truncated = Checkpoint::from_bytes(&bytes[..bytes.len() - 7], Path::new("m.ipfn"));
        assert!(truncated.unwrap_err().to_string().contains("corrupt"));
        let garbage = Checkpoint::from_bytes(b"hello world, not a model", Path::new("x.ipfn"));
        assert!(garbage.unwrap_err().to_string().contains("x.ipfn"));
    }
}
