//! The learned side of "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft
//! Formation" (Secs. 3, 5 and 6): the transient phase's optimisation data, DNN and closed-loop
//! Monte Carlo ([`transient`], Sec. 3.2.1 and Table 2), the science phase's Pareto data and DNN
//! ([`science`], Sec. 3.2.2 and Table 3). Both DNNs are stored as F32 safetensors files, read and
//! written with `cohort_runtime::weights`.

pub mod science;
pub mod transient;
