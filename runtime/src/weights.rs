//! Weights files of learned models (safetensors): one checked reader ([`WeightsFile`]), one writer
//! ([`to_bytes`]) and one error ([`WeightsError`]) for every network a paper ships.
//!
//! Why here: an algorithm loads its weights in the agent process (and in the in-process reference
//! run), and every paper links this crate; the format is the same for every model (safetensors,
//! little-endian F32 or F64 tensors, at most one metadata entry holding a JSON object), so the
//! checks a file must pass before a number of it is used — it can be read, it is safetensors, the
//! tensor exists, its dtype and shape are the expected ones, every value is finite, the metadata
//! entry is there and names the expected format — are written once, and every failure names the
//! model, the file, the tensor and what was expected against what was found.
//!
//! What stays with a paper: its tensor names and shapes and the checks that need the model
//! (positive scales, Lipschitz bounds, a layer chain), reported through [`WeightsFile::invalid`]
//! so that they read like the generic ones.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use safetensors::tensor::TensorView;
use safetensors::{Dtype, SafeTensors};

/// Element type of a stored tensor (every value is read as f64).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Precision {
    F32,
    F64,
}

impl Precision {
    fn dtype(self) -> Dtype {
        match self {
            Precision::F32 => Dtype::F32,
            Precision::F64 => Dtype::F64,
        }
    }
}

/// A shape a tensor must have: each dimension a fixed size or any (`None`, written `_`).
fn dims_text(dims: &[Option<usize>]) -> String {
    let d: Vec<String> = dims.iter().map(|d| d.map_or("_".to_string(), |n| n.to_string())).collect();
    format!("[{}]", d.join(", "))
}

/// What is wrong with a weights file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Problem {
    #[error("cannot read: {0}")]
    Read(String),
    #[error("not a safetensors file ({0})")]
    NotSafetensors(String),
    #[error("tensor {name:?} is missing")]
    MissingTensor { name: String },
    #[error("tensor {name:?} is {found}, expected {expected:?}")]
    Dtype { name: String, expected: Precision, found: String },
    #[error("tensor {name:?} has shape {found:?}, expected {}", dims_text(expected))]
    Shape { name: String, expected: Vec<Option<usize>>, found: Vec<usize> },
    #[error("tensor {name:?} value {index} (flat index) is not finite ({value})")]
    NotFinite { name: String, index: usize, value: f64 },
    #[error("no {key:?} metadata: not {what} weights file")]
    MissingMetadata { key: String, what: String },
    #[error("metadata {key:?} is not JSON ({reason})")]
    MetadataNotJson { key: String, reason: String },
    #[error("metadata format is {found:?}, expected {expected:?}")]
    Format { expected: String, found: Option<String> },
    /// A check of the model's own (a scale, a bound, the layer chain), in its words.
    #[error("{0}")]
    Invalid(String),
}

/// A weights file that cannot be used: which model's, which file, and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{model} weights {}: {problem}", file.display())]
pub struct WeightsError {
    /// The model the file was read for, e.g. "SN-DNN".
    pub model: &'static str,
    pub file: PathBuf,
    pub problem: Problem,
}

impl WeightsError {
    pub fn new(model: &'static str, file: &Path, problem: Problem) -> Self {
        Self { model, file: file.to_path_buf(), problem }
    }

    /// A model's own check failed: `reason` in its words.
    pub fn invalid(model: &'static str, file: &Path, reason: impl Into<String>) -> Self {
        Self::new(model, file, Problem::Invalid(reason.into()))
    }
}

/// A weights file's bytes (for [`WeightsFile::parse`], which borrows them).
pub fn read(model: &'static str, path: &Path) -> Result<Vec<u8>, WeightsError> {
    std::fs::read(path).map_err(|e| WeightsError::new(model, path, Problem::Read(e.to_string())))
}

/// A parsed safetensors file read for `model`; `file` names it in every error.
pub struct WeightsFile<'a> {
    model: &'static str,
    file: PathBuf,
    tensors: SafeTensors<'a>,
    metadata: HashMap<String, String>,
}

impl<'a> WeightsFile<'a> {
    /// Parse `bytes` (a whole file); `file` only names it in errors.
    pub fn parse(model: &'static str, bytes: &'a [u8], file: &Path) -> Result<Self, WeightsError> {
        let bad =
            |e: safetensors::SafeTensorError| WeightsError::new(model, file, Problem::NotSafetensors(e.to_string()));
        let (_, header) = SafeTensors::read_metadata(bytes).map_err(bad)?;
        let tensors = SafeTensors::deserialize(bytes).map_err(bad)?;
        let metadata = header.metadata().clone().unwrap_or_default();
        Ok(Self { model, file: file.to_path_buf(), tensors, metadata })
    }

    /// An error about this file.
    pub fn error(&self, problem: Problem) -> WeightsError {
        WeightsError::new(self.model, &self.file, problem)
    }

    /// A model's own check failed on this file: `reason` in its words.
    pub fn invalid(&self, reason: impl Into<String>) -> WeightsError {
        self.error(Problem::Invalid(reason.into()))
    }

    /// Every tensor name, sorted.
    pub fn names(&self) -> Vec<&str> {
        let mut n: Vec<&str> = self.tensors.names();
        n.sort_unstable();
        n
    }

    pub fn contains(&self, name: &str) -> bool {
        self.tensors.names().contains(&name)
    }

    /// The shape of tensor `name`.
    pub fn shape(&self, name: &str) -> Result<Vec<usize>, WeightsError> {
        let t = self.view(name)?;
        Ok(t.shape().to_vec())
    }

    fn view(&self, name: &str) -> Result<TensorView<'_>, WeightsError> {
        self.tensors.tensor(name).map_err(|_| self.error(Problem::MissingTensor { name: name.into() }))
    }

    /// Tensor `name`, of `precision` and exactly `shape`, every value finite, as f64 (row-major).
    pub fn tensor(&self, name: &str, precision: Precision, shape: &[usize]) -> Result<Vec<f64>, WeightsError> {
        let dims: Vec<Option<usize>> = shape.iter().map(|d| Some(*d)).collect();
        self.tensor_dims(name, precision, &dims).map(|(_, v)| v)
    }

    /// Tensor `name`, of `precision` and of a shape matching `dims` (`None`: any size), every value
    /// finite: its shape and its values as f64 (row-major).
    pub fn tensor_dims(
        &self,
        name: &str,
        precision: Precision,
        dims: &[Option<usize>],
    ) -> Result<(Vec<usize>, Vec<f64>), WeightsError> {
        let t = self.view(name)?;
        if t.dtype() != precision.dtype() {
            let found = format!("{:?}", t.dtype());
            return Err(self.error(Problem::Dtype { name: name.into(), expected: precision, found }));
        }
        let fits = t.shape().len() == dims.len() && t.shape().iter().zip(dims).all(|(s, d)| d.is_none_or(|d| d == *s));
        if !fits {
            let found = t.shape().to_vec();
            return Err(self.error(Problem::Shape { name: name.into(), expected: dims.to_vec(), found }));
        }
        let values: Vec<f64> = match precision {
            Precision::F32 => {
                t.data().chunks_exact(4).map(|c| f64::from(f32::from_le_bytes([c[0], c[1], c[2], c[3]]))).collect()
            }
            Precision::F64 => {
                t.data().chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes"))).collect()
            }
        };
        if let Some(index) = values.iter().position(|x| !x.is_finite()) {
            return Err(self.error(Problem::NotFinite { name: name.into(), index, value: values[index] }));
        }
        Ok((t.shape().to_vec(), values))
    }

    /// The metadata entry `key`: a JSON object whose `format` is `format`; `what` names the kind
    /// of file when the entry is missing ("an SN-DNN").
    pub fn metadata_json(&self, key: &str, format: &str, what: &str) -> Result<serde_json::Value, WeightsError> {
        let text = self
            .metadata
            .get(key)
            .ok_or_else(|| self.error(Problem::MissingMetadata { key: key.into(), what: what.into() }))?;
        let value: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| self.error(Problem::MetadataNotJson { key: key.into(), reason: e.to_string() }))?;
        let found = value.get("format").and_then(|f| f.as_str());
        if found != Some(format) {
            let found = found.map(String::from);
            return Err(self.error(Problem::Format { expected: format.into(), found }));
        }
        Ok(value)
    }
}

/// The values of a tensor to write.
#[derive(Debug, Clone, Copy)]
pub enum Values<'v> {
    F32(&'v [f32]),
    F64(&'v [f64]),
    /// f64 values stored as F32 (rounded to nearest).
    F64AsF32(&'v [f64]),
}

impl Values<'_> {
    fn len(&self) -> usize {
        match self {
            Values::F32(v) => v.len(),
            Values::F64(v) | Values::F64AsF32(v) => v.len(),
        }
    }

    fn bytes(&self) -> (Dtype, Vec<u8>) {
        match self {
            Values::F32(v) => (Dtype::F32, v.iter().flat_map(|x| x.to_le_bytes()).collect()),
            Values::F64(v) => (Dtype::F64, v.iter().flat_map(|x| x.to_le_bytes()).collect()),
            Values::F64AsF32(v) => (Dtype::F32, v.iter().flat_map(|x| (*x as f32).to_le_bytes()).collect()),
        }
    }
}

/// One tensor to write.
#[derive(Debug, Clone)]
pub struct Tensor<'v> {
    pub name: String,
    pub shape: Vec<usize>,
    pub values: Values<'v>,
}

impl<'v> Tensor<'v> {
    pub fn new(name: impl Into<String>, shape: Vec<usize>, values: Values<'v>) -> Self {
        Self { name: name.into(), shape, values }
    }
}

/// The bytes of a weights file for `model` holding `tensors` and, if given, one metadata entry
/// (key, JSON value). Deterministic: the same tensors and metadata give the same bytes. A tensor
/// whose values do not fill its shape is an error.
pub fn to_bytes(
    model: &'static str,
    tensors: &[Tensor<'_>],
    metadata: Option<(&str, &serde_json::Value)>,
) -> Result<Vec<u8>, WeightsError> {
    let written = Path::new("(being written)");
    let owned: Vec<(Dtype, Vec<u8>)> = tensors.iter().map(|t| t.values.bytes()).collect();
    let mut views = Vec::with_capacity(tensors.len());
    for (t, (dtype, data)) in tensors.iter().zip(&owned) {
        if t.shape.iter().product::<usize>() != t.values.len() {
            let reason = format!("tensor {:?}: {} values do not fill shape {:?}", t.name, t.values.len(), t.shape);
            return Err(WeightsError::invalid(model, written, reason));
        }
        let view = TensorView::new(*dtype, t.shape.clone(), data)
            .map_err(|e| WeightsError::invalid(model, written, format!("tensor {:?}: {e}", t.name)))?;
        views.push((t.name.clone(), view));
    }
    // One metadata key: a HashMap of one entry serialises the same way every time.
    let meta: Option<HashMap<String, String>> = metadata.map(|(k, v)| [(k.to_string(), v.to_string())].into());
    safetensors::serialize(views, meta).map_err(|e| WeightsError::invalid(model, written, e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(tensors: &[Tensor<'_>], meta: Option<(&str, &serde_json::Value)>) -> Vec<u8> {
        to_bytes("test", tensors, meta).expect("writes")
    }

    #[test]
    fn a_file_round_trips_and_every_check_names_the_tensor() {
        let w = [1.0f32, 2.0, 3.0, 4.0, 5.0, f32::NAN];
        let s = [0.5f64, 1.5];
        let meta = serde_json::json!({ "format": "fmt-v1", "n": 2 });
        let bytes = file(
            &[Tensor::new("w", vec![2, 2], Values::F32(&w[..4])), Tensor::new("s", vec![2], Values::F64(&s))],
            Some(("key", &meta)),
        );
        let f = WeightsFile::parse("test", &bytes, Path::new("a.safetensors")).unwrap();
        assert_eq!(f.names(), ["s", "w"]);
        assert_eq!(f.tensor("w", Precision::F32, &[2, 2]).unwrap(), [1.0, 2.0, 3.0, 4.0]);
        assert_eq!(f.tensor_dims("s", Precision::F64, &[None]).unwrap(), (vec![2], s.to_vec()));
        assert_eq!(f.metadata_json("key", "fmt-v1", "a test").unwrap(), meta);
        let e = |r: Result<Vec<f64>, WeightsError>| r.unwrap_err().to_string();
        assert_eq!(
            e(f.tensor("w", Precision::F32, &[4])),
            "test weights a.safetensors: tensor \"w\" has shape [2, 2], expected [4]"
        );
        assert!(e(f.tensor("w", Precision::F64, &[2, 2])).ends_with("tensor \"w\" is F32, expected F64"));
        assert!(e(f.tensor("x", Precision::F64, &[2])).ends_with("tensor \"x\" is missing"));
        let found = f.tensor_dims("w", Precision::F32, &[None, Some(3)]).unwrap_err().to_string();
        assert!(found.ends_with("expected [_, 3]"), "{found}");
        let m = f.metadata_json("key", "fmt-v2", "a test").unwrap_err().to_string();
        assert!(m.contains("format is Some(\"fmt-v1\"), expected \"fmt-v2\""), "{m}");
        let m = f.metadata_json("other", "fmt-v1", "a test").unwrap_err().to_string();
        assert!(m.ends_with("no \"other\" metadata: not a test weights file"), "{m}");
        // A non-finite value, a file that is no safetensors, a file that cannot be read.
        let nan = file(&[Tensor::new("w", vec![3, 2], Values::F32(&w))], None);
        let f = WeightsFile::parse("test", &nan, Path::new("n.safetensors")).unwrap();
        assert!(
            e(f.tensor("w", Precision::F32, &[3, 2]))
                .ends_with("tensor \"w\" value 5 (flat index) is not finite (NaN)")
        );
        let junk = WeightsFile::parse("test", b"junk", Path::new("j.safetensors")).err().unwrap().to_string();
        assert!(junk.starts_with("test weights j.safetensors: not a safetensors file"), "{junk}");
        let missing = read("test", Path::new("/nonexistent/x.safetensors")).unwrap_err().to_string();
        assert!(missing.contains("/nonexistent/x.safetensors: cannot read"), "{missing}");
    }

    #[test]
    fn values_that_do_not_fill_the_shape_are_refused_and_files_are_deterministic() {
        let v = [1.0f64, 2.0, 3.0];
        let e = to_bytes("test", &[Tensor::new("v", vec![2, 2], Values::F64AsF32(&v))], None).unwrap_err();
        assert!(e.to_string().contains("tensor \"v\": 3 values do not fill shape [2, 2]"), "{e}");
        let meta = serde_json::json!({ "format": "f" });
        let t = [Tensor::new("v", vec![3], Values::F64AsF32(&v))];
        assert_eq!(file(&t, Some(("k", &meta))), file(&t, Some(("k", &meta))));
    }
}
