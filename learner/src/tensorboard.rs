//! TensorBoard event files beside `metrics.csv`: `RUN/tb/events.out.tfevents.<secs>.fulcrum`,
//! readable by `tensorboard --logdir runs` and `wandb sync`.
//!
//! The file is a sequence of records, each
//!
//! ```text
//! u64 length (little endian) | u32 masked_crc32c(length bytes) | data | u32 masked_crc32c(data)
//! ```
//!
//! with `masked(c) = ((c >> 15) | (c << 17)) + 0xa282ead8` and CRC-32C (Castagnoli,
//! reflected polynomial 0x82f63b78). Each `data` is a protobuf `Event` (tensorflow's
//! `event.proto`), written here by hand since only a few fields are used:
//!
//! ```text
//! Event   { double wall_time = 1; int64 step = 2; string file_version = 3; Summary summary = 5; }
//! Summary { repeated Value value = 1; }
//! Value   { string tag = 1; float simple_value = 2; SummaryMetadata metadata = 9; TensorProto tensor = 8; }
//! SummaryMetadata { PluginData plugin_data = 1; }   PluginData { string plugin_name = 1; }
//! TensorProto { int32 dtype = 1 (7 = string); TensorShapeProto tensor_shape = 2; repeated bytes string_val = 8; }
//! ```
//!
//! The first event names the format (`brain.Event:2`), the second holds the run's
//! `config.toml` as text (the text plugin), then one event per metrics row: every
//! column as a scalar whose tag is the column's name, at step = env steps (values that
//! are not finite, such as the success rate of an update in which no episode ended, are
//! left out, as `metrics.csv` leaves them empty). With `train --eval-every`, each
//! periodic evaluation adds `eval/success_rate`, `eval/return`, `eval/episode_length`,
//! `eval/tool_use` and `eval/tool_choice` (where a tool fits the task) at its env steps. `metrics.csv` and `eval.csv` stay the record: on
//! `--resume` the events are written again from the rows they keep.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use crate::evalcsv::EvalRow;
use crate::metrics::{MetricsRow, METRICS_COLUMNS};

/// CRC-32C of `data` (bitwise-reflected, table-driven).
pub fn crc32c(data: &[u8]) -> u32 {
    const fn table() -> [u32; 256] {
        let mut t = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    (c >> 1) ^ 0x82f6_3b78
                } else {
                    c >> 1
                };
                k += 1;
            }
            t[i] = c;
            i += 1;
        }
        t
    }
    const TABLE: [u32; 256] = table();
    let mut c = !0u32;
    for &b in data {
        c = TABLE[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}

/// TensorFlow's masked CRC.
pub fn masked_crc(data: &[u8]) -> u32 {
    let c = crc32c(data);
    (c.rotate_right(15)).wrapping_add(0xa282_ead8)
}

/// One record: length, its masked CRC, the data, its masked CRC.
pub fn record(data: &[u8]) -> Vec<u8> {
    let len = (data.len() as u64).to_le_bytes();
    let mut out = Vec::with_capacity(data.len() + 16);
    out.extend_from_slice(&len);
    out.extend_from_slice(&masked_crc(&len).to_le_bytes());
    out.extend_from_slice(data);
    out.extend_from_slice(&masked_crc(data).to_le_bytes());
    out
}

/// Protobuf wire encoding of the few field kinds used.
mod pb {
    pub fn varint(out: &mut Vec<u8>, mut v: u64) {
        while v >= 0x80 {
            out.push((v as u8) | 0x80);
            v >>= 7;
        }
        out.push(v as u8);
    }

    fn key(out: &mut Vec<u8>, field: u32, wire: u32) {
        varint(out, ((field << 3) | wire) as u64);
    }

    pub fn int(out: &mut Vec<u8>, field: u32, v: u64) {
        key(out, field, 0);
        varint(out, v);
    }

    pub fn double(out: &mut Vec<u8>, field: u32, v: f64) {
        key(out, field, 1);
        out.extend_from_slice(&v.to_le_bytes());
    }

    pub fn float(out: &mut Vec<u8>, field: u32, v: f32) {
        key(out, field, 5);
        out.extend_from_slice(&v.to_le_bytes());
    }

    pub fn bytes(out: &mut Vec<u8>, field: u32, v: &[u8]) {
        key(out, field, 2);
        varint(out, v.len() as u64);
        out.extend_from_slice(v);
    }
}

/// An `Event` with a `file_version`.
fn version_event(wall_time: f64) -> Vec<u8> {
    let mut e = Vec::new();
    pb::double(&mut e, 1, wall_time);
    pb::bytes(&mut e, 3, b"brain.Event:2");
    e
}

/// An `Event` at `step` whose summary holds `values`.
fn summary_event(wall_time: f64, step: u64, values: &[Vec<u8>]) -> Vec<u8> {
    let mut summary = Vec::new();
    for v in values {
        pb::bytes(&mut summary, 1, v);
    }
    let mut e = Vec::new();
    pb::double(&mut e, 1, wall_time);
    pb::int(&mut e, 2, step);
    pb::bytes(&mut e, 5, &summary);
    e
}

/// A scalar `Summary.Value`.
fn scalar_value(tag: &str, v: f32) -> Vec<u8> {
    let mut out = Vec::new();
    pb::bytes(&mut out, 1, tag.as_bytes());
    pb::float(&mut out, 2, v);
    out
}

/// A text `Summary.Value` (the text plugin: a string tensor of shape []).
fn text_value(tag: &str, text: &str) -> Vec<u8> {
    let mut plugin = Vec::new();
    pb::bytes(&mut plugin, 1, b"text");
    let mut meta = Vec::new();
    pb::bytes(&mut meta, 1, &plugin);
    let mut tensor = Vec::new();
    pb::int(&mut tensor, 1, 7); // DT_STRING
    pb::bytes(&mut tensor, 2, &[]); // shape [] (a scalar)
    pb::bytes(&mut tensor, 8, text.as_bytes());
    let mut out = Vec::new();
    pb::bytes(&mut out, 1, tag.as_bytes());
    pb::bytes(&mut out, 9, &meta);
    pb::bytes(&mut out, 8, &tensor);
    out
}

/// Every column of a row as `(tag, value)`, the finite ones only.
pub fn row_scalars(row: &MetricsRow) -> Vec<(&'static str, f64)> {
    let csv = row.csv();
    METRICS_COLUMNS
        .iter()
        .zip(csv.split(','))
        .filter_map(|(&tag, field)| field.parse::<f64>().ok().map(|v| (tag, v)))
        .filter(|(_, v)| v.is_finite())
        .collect()
}

/// The events of one metrics row.
fn row_event(start: f64, row: &MetricsRow) -> Vec<u8> {
    let values: Vec<Vec<u8>> = row_scalars(row)
        .into_iter()
        .map(|(tag, v)| scalar_value(tag, v as f32))
        .collect();
    summary_event(start + row.wall_s.max(0.0), row.env_steps, &values)
}

/// The events of one periodic evaluation (`eval/...` scalars at its env steps).
fn eval_event(wall: f64, row: &EvalRow) -> Vec<u8> {
    let values: Vec<Vec<u8>> = row
        .scalars()
        .into_iter()
        .filter(|(_, v)| v.is_finite())
        .map(|(tag, v)| scalar_value(tag, v as f32))
        .collect();
    summary_event(wall, row.env_steps, &values)
}

/// The event file of a run.
#[derive(Debug)]
pub struct EventWriter {
    file: File,
    path: PathBuf,
    /// UNIX time at which the run's `wall_s` was 0.
    start: f64,
}

fn now() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

impl EventWriter {
    /// Start the run's events in `dir` (made if missing; earlier event files there are
    /// replaced): the version, `config` as text, then `rows` (those `metrics.csv` holds
    /// on a resume) and `evals` (the periodic evaluations `eval.csv` holds, each at the
    /// wall time of its update's row). `wall_s` is the run's wall time so far.
    pub fn create(
        dir: &Path,
        config: &str,
        rows: &[MetricsRow],
        evals: &[EvalRow],
        wall_s: f64,
    ) -> std::io::Result<EventWriter> {
        std::fs::create_dir_all(dir)?;
        let t = now();
        let start = t - wall_s.max(0.0);
        let mut data = record(&version_event(t));
        data.extend(record(&summary_event(
            start,
            0,
            &[text_value("config", &format!("```\n{config}\n```"))],
        )));
        for r in rows {
            data.extend(record(&row_event(start, r)));
        }
        for e in evals {
            let wall = rows
                .iter()
                .find(|r| r.update == e.update)
                .map_or(0.0, |r| r.wall_s);
            data.extend(record(&eval_event(start + wall.max(0.0), e)));
        }
        let name = format!("events.out.tfevents.{}.fulcrum", t as u64);
        let path = dir.join(&name);
        fulcrum_contracts::fsio::write_atomic(&path, &data)?;
        // Earlier files (a run resumed) hold rows this one has again or dropped.
        for entry in std::fs::read_dir(dir)?.flatten() {
            let p = entry.path();
            let other = p
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("events.out.tfevents.") && n != name);
            if other {
                std::fs::remove_file(&p)?;
            }
        }
        let file = std::fs::OpenOptions::new().append(true).open(&path)?;
        Ok(EventWriter { file, path, start })
    }

    /// Append one metrics row.
    pub fn append(&mut self, row: &MetricsRow) -> std::io::Result<()> {
        self.file.write_all(&record(&row_event(self.start, row)))
    }

    /// Append one periodic evaluation, at the run's wall time `wall_s`.
    pub fn append_eval(&mut self, row: &EvalRow, wall_s: f64) -> std::io::Result<()> {
        let event = eval_event(self.start + wall_s.max(0.0), row);
        self.file.write_all(&record(&event))
    }

    /// The file written.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32c_matches_the_standard_check_values() {
        // The check value of CRC-32C (RFC 3720, appendix B.4 and the catalogue of CRCs).
        assert_eq!(crc32c(b"123456789"), 0xe306_9283);
        assert_eq!(crc32c(&[0u8; 32]), 0x8a91_36aa);
        assert_eq!(crc32c(&[0xffu8; 32]), 0x62a8_ab43);
    }

    #[test]
    // The mask written as TensorFlow's `crc32c::Mask` writes it: the reference here.
    #[allow(clippy::manual_rotate)]
    fn a_record_frames_its_data_with_length_and_checksums() {
        let r = record(b"abc");
        assert_eq!(r.len(), 8 + 4 + 3 + 4);
        assert_eq!(&r[..8], &3u64.to_le_bytes());
        assert_eq!(&r[12..15], b"abc");
        let c = crc32c(b"abc");
        assert_eq!(
            u32::from_le_bytes(r[15..19].try_into().unwrap()),
            ((c >> 15) | (c << 17)).wrapping_add(0xa282_ead8)
        );
    }

    #[test]
    fn varints_are_little_endian_base_128() {
        let mut v = Vec::new();
        pb::varint(&mut v, 300);
        assert_eq!(v, [0xac, 0x02]);
    }
}
