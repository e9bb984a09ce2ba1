//! The F32 safetensors files of the learned models (the transient DNN, [`crate::learn::transient::dnn`],
//! and the science DNN, [`crate::learn::science::dnn`]): reading a file, one checked tensor, and writing
//! tensors. Each model keeps its own error type (naming which model's file); these return the
//! reason only.

use std::path::Path;

use safetensors::{Dtype, SafeTensors};

/// A weights file's bytes, or why it cannot be read.
pub fn read(path: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(path).map_err(|e| format!("cannot read: {e}"))
}

/// A file's tensors, or why the bytes are not a safetensors file.
pub fn open(bytes: &[u8]) -> Result<SafeTensors<'_>, String> {
    SafeTensors::deserialize(bytes).map_err(|e| format!("not a safetensors file ({e})"))
}

/// Tensor `name`: F32 of exactly `shape`, every value finite, as f64.
pub fn f32_tensor(st: &SafeTensors<'_>, name: &str, shape: &[usize]) -> Result<Vec<f64>, String> {
    let t = st.tensor(name).map_err(|_| format!("no tensor {name:?}"))?;
    if t.dtype() != Dtype::F32 {
        return Err(format!("tensor {name:?} is {:?}, expected F32", t.dtype()));
    }
    if t.shape() != shape {
        return Err(format!("tensor {name:?} has shape {:?}, expected {shape:?}", t.shape()));
    }
    let v: Vec<f64> =
        t.data().chunks_exact(4).map(|c| f64::from(f32::from_le_bytes([c[0], c[1], c[2], c[3]]))).collect();
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(format!("tensor {name:?} value {i} is not finite"));
    }
    Ok(v)
}

/// A file of `tensors` (name, shape, values), stored as F32 in this order, without metadata.
pub fn serialise_f32(tensors: &[(String, Vec<usize>, &[f64])]) -> Vec<u8> {
    use safetensors::tensor::TensorView;
    let bytes: Vec<Vec<u8>> =
        tensors.iter().map(|(_, _, v)| v.iter().flat_map(|x| (*x as f32).to_le_bytes()).collect()).collect();
    let views: Vec<(String, TensorView<'_>)> = tensors
        .iter()
        .zip(&bytes)
        .map(|((n, s, _), d)| (n.clone(), TensorView::new(Dtype::F32, s.clone(), d).expect("sizes match")))
        .collect();
    safetensors::serialize(views, None).expect("well-formed tensors serialise")
}
