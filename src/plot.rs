//! TEMPORARY STUB (the plot helper replaces this file).
#![allow(dead_code, missing_docs)]
use std::path::Path;
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{0}")]
    Io(String),
}
pub struct Heatmap<'a> {
    pub title: &'a str,
    pub values: &'a [Vec<Option<f64>>],
    pub rock: &'a [Vec<bool>],
    pub glyphs: Option<&'a [Vec<Option<char>>]>,
    pub unit: &'a str,
}
pub fn heatmap_png(_path: &Path, _h: &Heatmap) -> Result<(), PlotError> {
    Err(PlotError::Io("stub".into()))
}
pub struct Trace<'a> {
    pub title: &'a str,
    pub value_label: &'a str,
    pub values: &'a [f64],
    pub actions: &'a [Option<String>],
    pub category: Option<(&'a str, &'a [String], &'a [usize])>,
}
pub fn trace_png(_path: &Path, _t: &Trace) -> Result<(), PlotError> {
    Err(PlotError::Io("stub".into()))
}
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    std::fs::write(path, bytes)
}
