//! Model files: safetensors (readable from PyTorch / numpy with `safetensors.torch.load_file`)
//! with the architecture, scene box and format version as JSON in the header's metadata.
//!
//! Tensors of a NeRF under prefix `P` (empty for a plain model):
//! - `P grid.params` f32 `[entries, 2]`: the hash-grid fp32 master (the fp16 mirror is derived);
//! - `P density.{l}.weight`, `P colour.{l}.weight` f32 `[out, in]` per layer (PyTorch
//!   `nn.Linear` layout, no padding, no bias);
//! - `P occupancy.values` f32 `[res, res, res]` (z, y, x): per-cell optical thickness.
//!
//! Metadata: `format` = [`FORMAT`], `format_version` = [`FORMAT_VERSION`], `kind`, and
//! `P config`: `{"grid": {...}, "aabb": [[..],[..]], "occupancy": {...}}`; any extra keys the
//! writer adds (training settings) are informational.
//!
//! Writes are atomic ([`crate::files::write_atomic`]) and refuse non-finite weights; loading refuses
//! a truncated file, another format or version, shapes that do not match the config, and
//! non-finite weights — each with one line naming the file and the tensor or key.

use crate::encoding::{HashGridConfig, HashGridParams};
use crate::error::{Error, ErrorKind};
use crate::field::mix::{DensityMix, MixKind};
use crate::field::mixnet::{MixnetEncoding, MixnetParams};
use crate::field::model::Model;
use crate::field::residual::{ResidualConfig, ResidualField, ResidualModel, ResidualParams};
use crate::field::{NerfConfig, NerfField, NerfParams};
use crate::files::write_atomic;
use crate::geometry::ChangeRegion;
use crate::mlp::LayerShape;
use crate::render::{Aabb, OccupancyConfig, OccupancyGrid};
use crate::train::trainer::Nerf;
use glam::Vec3;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::Path;

/// `format` metadata value of every model file.
pub const FORMAT: &str = "residual-nerf-model";
/// Version of the layout above; files of another version are refused.
pub const FORMAT_VERSION: u32 = 1;
/// Largest model file read (bytes).
pub const MAX_MODEL_BYTES: u64 = 4 << 30;

/// Tensors and metadata of a model file, assembled before serialising.
#[derive(Default)]
pub struct ModelWriter {
    tensors: Vec<(String, Vec<usize>, Vec<u8>)>,
    metadata: HashMap<String, String>,
}

impl ModelWriter {
    /// A file of `kind` (`"nerf"`, `"residual"`).
    pub fn new(kind: &str) -> ModelWriter {
        let mut w = ModelWriter::default();
        w.meta("format", FORMAT);
        w.meta("format_version", &FORMAT_VERSION.to_string());
        w.meta("kind", kind);
        w
    }

    /// Sets a metadata key.
    pub fn meta(&mut self, key: &str, value: &str) {
        self.metadata.insert(key.to_string(), value.to_string());
    }

    /// Adds an f32 tensor, refusing non-finite values.
    pub fn tensor(&mut self, name: &str, shape: Vec<usize>, data: &[f32]) -> Result<(), String> {
        assert_eq!(shape.iter().product::<usize>(), data.len(), "model: tensor {name} shape mismatch");
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            return Err(format!("tensor '{name}' holds a non-finite value at {i} ({}); refusing to save", data[i]));
        }
        self.tensors.push((name.to_string(), shape, bytemuck::cast_slice(data).to_vec()));
        Ok(())
    }

    /// Adds a NeRF's tensors and config under `prefix`.
    pub fn nerf(&mut self, prefix: &str, nerf: &Nerf) -> Result<(), String> {
        self.nerf_parts(prefix, &nerf.field, &nerf.params, &nerf.occupancy)
    }

    /// Adds a NeRF field's tensors and config (with `occupancy`) under `prefix`.
    pub fn nerf_parts(
        &mut self,
        prefix: &str,
        field: &NerfField,
        params: &NerfParams,
        occupancy: &OccupancyGrid,
    ) -> Result<(), String> {
        let cfg = field.config();
        self.meta(&format!("{prefix}config"), &config_json(cfg, occupancy.config()).to_string());
        let entries = params.grid.master.len() / 2;
        self.tensor(&format!("{prefix}grid.params"), vec![entries, 2], &params.grid.master)?;
        self.mlp(&format!("{prefix}density"), params.density.weights(), field.density_layers())?;
        self.mlp(&format!("{prefix}colour"), params.colour.weights(), field.colour_layers())?;
        let r = occupancy.config().resolution as usize;
        self.tensor(&format!("{prefix}occupancy.values"), vec![r, r, r], occupancy.values())?;
        Ok(())
    }

    /// Adds an MLP's layers as `{name}.{l}.weight` `[out, in]` (no padding).
    pub fn mlp(&mut self, name: &str, w: &[f32], layers: &[LayerShape]) -> Result<(), String> {
        for (l, s) in layers.iter().enumerate() {
            let t: Vec<f32> =
                (0..s.o_real).flat_map(|j| (0..s.k_real).map(move |k| w[s.offset + k * s.o + j])).collect();
            self.tensor(&format!("{name}.{l}.weight"), vec![s.o_real, s.k_real], &t)?;
        }
        Ok(())
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Result<Vec<u8>, String> {
        let views: Vec<(String, TensorView<'_>)> = self
            .tensors
            .iter()
            .map(|(n, s, d)| (n.clone(), TensorView::new(Dtype::F32, s.clone(), d).expect("shape checked on insert")))
            .collect();
        safetensors::serialize(views, Some(self.metadata.clone())).map_err(|e| format!("cannot serialise: {e}"))
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), String> {
        let bytes = self.to_bytes().map_err(|e| format!("{}: {e}", path.display()))?;
        write_atomic(path, &bytes)
    }
}

fn config_json(cfg: &NerfConfig, occ: &OccupancyConfig) -> Value {
    json!({
        "grid": grid_json(&cfg.grid),
        "aabb": [cfg.aabb.min.to_array(), cfg.aabb.max.to_array()],
        "occupancy": {
            "resolution": occ.resolution, "steps_per_diagonal": occ.steps_per_diagonal,
            "max_samples": occ.max_samples, "warmup_steps": occ.warmup_steps, "decay": occ.decay,
            "near": occ.near,
        },
    })
}

/// A parsed model file: its metadata and tensors (borrowing the bytes).
pub struct ModelReader<'a> {
    st: SafeTensors<'a>,
    metadata: HashMap<String, String>,
}

impl<'a> ModelReader<'a> {
    /// Parses and checks the header: format and version.
    pub fn parse(bytes: &'a [u8]) -> Result<ModelReader<'a>, Error> {
        if bytes.len() < 8 {
            return Err(Error::corrupt(format!("not a model file: {} bytes (truncated or empty)", bytes.len())));
        }
        let (_, meta) = SafeTensors::read_metadata(bytes)
            .map_err(|e| Error::corrupt(format!("not a model file, or truncated (safetensors: {e})")))?;
        let metadata = meta.metadata().clone().unwrap_or_default();
        let unsupported = |m: String| Error::new(ErrorKind::Unsupported, m);
        match metadata.get("format").map(String::as_str) {
            Some(FORMAT) => {}
            Some(other) => return Err(unsupported(format!("not a residual-nerf model (format '{other}')"))),
            None => return Err(unsupported("not a residual-nerf model (no 'format' in the metadata)".into())),
        }
        let version = metadata.get("format_version").map(String::as_str).unwrap_or("?");
        if version != FORMAT_VERSION.to_string() {
            return Err(unsupported(format!("format version {version}, this build reads version {FORMAT_VERSION}")));
        }
        let st = SafeTensors::deserialize(bytes)
            .map_err(|e| Error::corrupt(format!("corrupt model file (safetensors: {e})")))?;
        Ok(ModelReader { st, metadata })
    }

    /// All metadata entries.
    pub fn metadata(&self) -> &HashMap<String, String> {
        &self.metadata
    }

    /// A metadata value.
    pub fn meta(&self, key: &str) -> Result<&str, String> {
        self.metadata.get(key).map(String::as_str).ok_or_else(|| format!("metadata key '{key}' missing"))
    }

    /// A tensor's shape.
    pub fn shape(&self, name: &str) -> Result<Vec<usize>, String> {
        Ok(self.st.tensor(name).map_err(|_| format!("tensor '{name}' missing"))?.shape().to_vec())
    }

    /// An f32 tensor of exactly `shape`, all finite.
    pub fn tensor(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>, String> {
        let t = self.st.tensor(name).map_err(|_| format!("tensor '{name}' missing"))?;
        if t.dtype() != Dtype::F32 {
            return Err(format!("tensor '{name}' is {:?}, expected F32", t.dtype()));
        }
        if t.shape() != shape {
            return Err(format!("tensor '{name}' has shape {:?}, the config needs {shape:?}", t.shape()));
        }
        let v: Vec<f32> = t.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(format!("tensor '{name}' holds a non-finite value at {i}"));
        }
        Ok(v)
    }

    /// An MLP's flat (padded) weight buffer of length `n` from its `{name}.{l}.weight` tensors.
    pub fn mlp(&self, name: &str, layers: &[LayerShape], n: usize) -> Result<Vec<f32>, String> {
        let mut flat = vec![0.0; n];
        for (l, s) in layers.iter().enumerate() {
            let t = self.tensor(&format!("{name}.{l}.weight"), &[s.o_real, s.k_real])?;
            for j in 0..s.o_real {
                for k in 0..s.k_real {
                    flat[s.offset + k * s.o + j] = t[j * s.k_real + k];
                }
            }
        }
        Ok(flat)
    }

    /// The NeRF stored under `prefix`.
    pub fn nerf(&self, prefix: &str) -> Result<Nerf, String> {
        let key = format!("{prefix}config");
        let cfg: Value =
            serde_json::from_str(self.meta(&key)?).map_err(|e| format!("metadata '{key}' is not JSON: {e}"))?;
        let (config, occ) = parse_config(&cfg).map_err(|e| format!("metadata '{key}': {e}"))?;
        let field = NerfField::new(config.clone());
        let entries = field.grid().entries();
        let master = self.tensor(&format!("{prefix}grid.params"), &[entries, 2])?;
        let density = self.mlp(&format!("{prefix}density"), field.density_layers(), field.density_params())?;
        let colour = self.mlp(&format!("{prefix}colour"), field.colour_layers(), field.colour_params())?;
        let r = occ.resolution as usize;
        let values = self.tensor(&format!("{prefix}occupancy.values"), &[r, r, r])?;
        if let Some(i) = values.iter().position(|&v| v < 0.0) {
            return Err(format!("tensor '{prefix}occupancy.values' holds a negative value at {i}"));
        }
        let params = NerfParams {
            grid: HashGridParams::from_master(master),
            density: field.density_params_from(density),
            colour: field.colour_params_from(colour),
        };
        let occupancy = OccupancyGrid::from_values(config.aabb, occ, values);
        Ok(Nerf { field, params, occupancy })
    }
}

fn int(v: &Value, key: &str, lo: u64, hi: u64) -> Result<u64, String> {
    match v.get(key).and_then(Value::as_u64) {
        Some(x) if (lo..=hi).contains(&x) => Ok(x),
        Some(x) => Err(format!("'{key}' = {x} is outside {lo}..={hi}")),
        None => Err(format!("'{key}' missing or not an integer")),
    }
}

fn grid_json(g: &HashGridConfig) -> Value {
    json!({
        "levels": g.levels, "log2_table_size": g.log2_table_size,
        "base_resolution": g.base_resolution, "finest_resolution": g.finest_resolution,
    })
}

fn parse_grid(g: &Value) -> Result<HashGridConfig, String> {
    let base = int(g, "base_resolution", 1, 1 << 20)? as u32;
    Ok(HashGridConfig {
        levels: int(g, "levels", 1, 32)? as usize,
        log2_table_size: int(g, "log2_table_size", 4, 26)? as u32,
        base_resolution: base,
        finest_resolution: int(g, "finest_resolution", base as u64, 1 << 20)? as u32,
    })
}

fn parse_config(v: &Value) -> Result<(NerfConfig, OccupancyConfig), String> {
    let grid = parse_grid(v.get("grid").ok_or("'grid' missing")?)?;
    let corner = |c: Option<&Value>| -> Option<Vec3> {
        let a = c?.as_array().filter(|a| a.len() == 3)?;
        let x: Vec<f32> = a.iter().map(|x| x.as_f64().map(|x| x as f32)).collect::<Option<_>>()?;
        Some(Vec3::new(x[0], x[1], x[2]))
    };
    let aabb = v.get("aabb").and_then(|a| Some(Aabb { min: corner(a.get(0))?, max: corner(a.get(1))? }));
    let aabb = aabb
        .filter(|b| {
            b.min.cmplt(b.max).all() && b.size().is_finite() && b.max.abs().max(b.min.abs()).max_element() < 1e6
        })
        .ok_or("'aabb' missing, empty or absurd")?;
    let o = v.get("occupancy").ok_or("'occupancy' missing")?;
    let decay =
        o.get("decay").and_then(Value::as_f64).filter(|d| (0.0..=1.0).contains(d)).ok_or("'decay' not in [0, 1]")?;
    let occ = OccupancyConfig {
        resolution: int(o, "resolution", 1, 512)? as u32,
        steps_per_diagonal: int(o, "steps_per_diagonal", 1, 1 << 16)? as u32,
        max_samples: int(o, "max_samples", 1, 1 << 16)? as u32,
        warmup_steps: int(o, "warmup_steps", 0, u32::MAX as u64)? as u32,
        decay: decay as f32,
        near: o
            .get("near")
            .and_then(Value::as_f64)
            .filter(|n| (0.0..1e6).contains(n))
            .ok_or("'near' not in [0, 1e6)")? as f32,
    };
    Ok((NerfConfig { grid, aabb }, occ))
}

/// Reads a whole model file (size-limited), errors naming the file.
pub fn read_model_bytes(path: &Path) -> Result<Vec<u8>, Error> {
    crate::files::read_limited(path, MAX_MODEL_BYTES)
        .map_err(|e| Error::new(ErrorKind::Io, format!("{}: model file: {e}", path.display())))
}

/// A trainable field a model file holds: what a model file of it contains, given its
/// parameters and occupancy grid (the trainer's checkpoints use this while training).
pub trait ModelFile: Model {
    /// The model's tensors and metadata.
    fn writer(&self, params: &Self::Params, occupancy: &OccupancyGrid) -> Result<ModelWriter, String>;
}

impl ModelFile for NerfField {
    fn writer(&self, params: &NerfParams, occupancy: &OccupancyGrid) -> Result<ModelWriter, String> {
        let mut w = ModelWriter::new("nerf");
        w.nerf_parts("", self, params, occupancy)?;
        Ok(w)
    }
}

impl ModelFile for ResidualField {
    fn writer(&self, params: &ResidualParams, occupancy: &OccupancyGrid) -> Result<ModelWriter, String> {
        let mut w = ModelWriter::new("residual");
        w.nerf("background.", &self.background)?;
        w.nerf_parts("residual.", self.residual(), &params.residual, occupancy)?;
        w.meta("mix", mix_name(self.kind()));
        let mixnet = self.mixnet();
        match mixnet.grid() {
            Some(grid) => {
                w.meta("mixnet_grid", &grid_json(grid.config()).to_string());
                let entries = params.mixnet.grid.master.len() / 2;
                w.tensor("mixnet.grid.params", vec![entries, 2], &params.mixnet.grid.master)?;
            }
            None => w.meta("mixnet_grid", "\"shared\""),
        }
        w.mlp("mixnet", params.mixnet.mlp.weights(), mixnet.mlp().layers())?;
        if let Some(region) = self.region() {
            // Up to 256³ cells the indices (exact in f32 up to 2^24), a finer region its cells'
            // coordinates, one row of three per cell (each below 512).
            if region.resolution() > crate::geometry::region::MAX_RESOLUTION {
                return Err(format!(
                    "change region of {}^3 cells: model files hold at most {}^3",
                    region.resolution(),
                    crate::geometry::region::MAX_RESOLUTION
                ));
            }
            w.meta("region_resolution", &region.resolution().to_string());
            let cells = region.cells();
            match region.resolution() <= INDEXED_REGION {
                true => {
                    let cells: Vec<f32> = cells.iter().map(|&c| c as f32).collect();
                    w.tensor("region.cells", vec![cells.len()], &cells)?;
                }
                false => {
                    let r = region.resolution();
                    let xyz: Vec<f32> =
                        cells.iter().flat_map(|&c| [c % r, c / r % r, c / (r * r)]).map(|v| v as f32).collect();
                    w.tensor("region.cells", vec![cells.len(), 3], &xyz)?;
                }
            }
            if occupancy.is_frozen_outside_pins() {
                w.meta("occupancy_frozen_outside_region", "true");
            }
        }
        if let Some(sigma) = self.solid_background() {
            w.meta("solid_background_sigma", &sigma.to_string());
        }
        Ok(w)
    }
}

/// Saves `field` with `params` and `occupancy` plus extra informational metadata, atomically.
pub fn save_model<M: ModelFile>(
    path: &Path,
    field: &M,
    params: &M::Params,
    occupancy: &OccupancyGrid,
    extra: &[(&str, String)],
) -> Result<(), Error> {
    let mut w = field.writer(params, occupancy).map_err(|e| Error::bad_input(format!("{}: {e}", path.display())))?;
    for (k, v) in extra {
        w.meta(k, v);
    }
    w.write(path).map_err(|e| Error::new(ErrorKind::Io, e))
}

/// Saves a plain NeRF (`kind = "nerf"`) with extra informational metadata.
pub fn save_nerf(path: &Path, nerf: &Nerf, extra: &[(&str, String)]) -> Result<(), Error> {
    save_model(path, &nerf.field, &nerf.params, &nerf.occupancy, extra)
}

/// Loads a plain NeRF from model-file bytes.
pub fn nerf_from_bytes(bytes: &[u8]) -> Result<Nerf, Error> {
    let r = ModelReader::parse(bytes)?;
    match r.meta("kind").map_err(Error::corrupt)? {
        "nerf" => r.nerf("").map_err(Error::corrupt),
        other => {
            Err(Error::new(ErrorKind::Unsupported, format!("model kind '{other}', expected a plain NeRF ('nerf')")))
        }
    }
}

/// Loads a plain NeRF; errors name the file.
pub fn load_nerf(path: &Path) -> Result<Nerf, Error> {
    let bytes = read_model_bytes(path)?;
    nerf_from_bytes(&bytes).map_err(|e| e.context(path.display()))
}

/// A model file of either kind.
pub enum LoadedModel {
    /// A plain NeRF (`kind = "nerf"`).
    Nerf(Box<Nerf>),
    /// A residual model (`kind = "residual"`), background embedded.
    Residual(Box<ResidualModel>),
}

fn mix_name(kind: MixKind) -> &'static str {
    match kind {
        MixKind::Mixnet(DensityMix::Raw) => "mixnet-raw",
        MixKind::Mixnet(DensityMix::Activated) => "mixnet-activated",
        MixKind::Sum => "sum",
    }
}

/// Saves a residual model (`kind = "residual"`): the frozen background under `background.`,
/// the residual NeRF (with the mixed field's occupancy grid) under `residual.`, the Mixnet
/// under `mixnet.`, and `mix` / `mixnet_grid` metadata (`"shared"` when the Mixnet reads the
/// residual's encoding; then there is no `mixnet.grid.params`). The background is embedded, so
/// the file is all a robot needs.
pub fn save_residual(path: &Path, m: &ResidualModel, extra: &[(&str, String)]) -> Result<(), Error> {
    save_model(path, &m.field, &m.params, &m.occupancy, extra)
}

/// Loads a model of either kind from model-file bytes.
pub fn model_from_bytes(bytes: &[u8]) -> Result<LoadedModel, Error> {
    model_from_reader(&ModelReader::parse(bytes)?)
}

/// Loads a model of either kind from a parsed model file (whose metadata the caller may read
/// too, without parsing the file again).
pub fn model_from_reader(r: &ModelReader<'_>) -> Result<LoadedModel, Error> {
    match r.meta("kind").map_err(Error::corrupt)? {
        "nerf" => Ok(LoadedModel::Nerf(Box::new(r.nerf("").map_err(Error::corrupt)?))),
        "residual" => {
            let background = r.nerf("background.").map_err(Error::corrupt)?;
            let res = r.nerf("residual.").map_err(Error::corrupt)?;
            if res.field.config().aabb != background.field.config().aabb {
                return Err(Error::new(ErrorKind::MismatchedBackground, "residual and background scene boxes differ"));
            }
            let kind = match r.meta("mix").map_err(Error::corrupt)? {
                "mixnet-raw" => MixKind::Mixnet(DensityMix::Raw),
                "mixnet-activated" => MixKind::Mixnet(DensityMix::Activated),
                "sum" => MixKind::Sum,
                other => {
                    return Err(Error::new(
                        ErrorKind::Unsupported,
                        format!("metadata 'mix' = '{other}' is not mixnet-raw, mixnet-activated or sum"),
                    ))
                }
            };
            residual_from(r, background, res, kind).map_err(Error::corrupt)
        }
        other => Err(Error::new(ErrorKind::Unsupported, format!("model kind '{other}' is not 'nerf' or 'residual'"))),
    }
}

/// The rest of a residual model file once its two NeRFs and mixing rule are read.
fn residual_from(r: &ModelReader<'_>, background: Nerf, res: Nerf, kind: MixKind) -> Result<LoadedModel, String> {
    let g: Value = serde_json::from_str(r.meta("mixnet_grid")?).map_err(|e| format!("metadata 'mixnet_grid': {e}"))?;
    let mixnet_encoding = match g.as_str() {
        Some("shared") => MixnetEncoding::Shared,
        _ => MixnetEncoding::Own(parse_grid(&g).map_err(|e| format!("metadata 'mixnet_grid': {e}"))?),
    };
    let config = ResidualConfig { residual: res.field.config().clone(), kind, mixnet: mixnet_encoding };
    let field = ResidualField::new(background, config);
    let mixnet = field.mixnet();
    let grid = match mixnet.grid() {
        Some(g) => HashGridParams::from_master(r.tensor("mixnet.grid.params", &[g.entries(), 2])?),
        None => HashGridParams::from_master(Vec::new()),
    };
    let mlp = mixnet.mlp_params_from(r.mlp("mixnet", mixnet.mlp().layers(), mixnet.mlp().n_params())?);
    let params = ResidualParams { residual: res.params, mixnet: MixnetParams { grid, mlp } };
    let mut occupancy = res.occupancy;
    let field = match r.meta("region_resolution").ok() {
        None => field,
        Some(text) => {
            let region = read_region(r, text, &field)?;
            if region.resolution().is_multiple_of(occupancy.config().resolution) {
                occupancy.pin(&region);
                if r.meta("occupancy_frozen_outside_region").ok() == Some("true") {
                    occupancy.freeze_outside_pins();
                }
            }
            field.with_region(region)
        }
    };
    let field = match r.meta("solid_background_sigma").ok() {
        None => field,
        Some(text) => match text.parse::<f32>() {
            Ok(sigma) if sigma > 0.0 && sigma.is_finite() && matches!(field.kind(), MixKind::Mixnet(_)) => {
                field.with_solid_background(sigma)
            }
            _ => {
                return Err(format!(
                    "metadata 'solid_background_sigma' = '{text}' is not a positive σ of a Mixnet model"
                ))
            }
        },
    };
    Ok(LoadedModel::Residual(Box::new(ResidualModel { field, params, occupancy })))
}

/// The change region of a residual model file (`region_resolution` metadata, `region.cells`).
fn read_region(r: &ModelReader<'_>, resolution: &str, field: &ResidualField) -> Result<ChangeRegion, String> {
    let max = crate::geometry::region::MAX_RESOLUTION;
    let res: u32 = resolution
        .parse()
        .ok()
        .filter(|v| (1..=max).contains(v))
        .ok_or_else(|| format!("metadata 'region_resolution' = '{resolution}' is not 1..={max}"))?;
    if !matches!(field.kind(), MixKind::Mixnet(_)) {
        return Err("a change region needs a Mixnet ('mix' is 'sum')".into());
    }
    let shape = r.shape("region.cells")?;
    // Indices up to 256³ cells, coordinates (rows of three) above.
    let indexed = res <= INDEXED_REGION;
    let fits = match indexed {
        true => shape.len() == 1,
        false => shape.len() == 2 && shape[1] == 3,
    };
    if !fits {
        let expected = if indexed { "one dimension" } else { "rows of 3 coordinates" };
        return Err(format!("tensor 'region.cells' has shape {shape:?}, expected {expected} for {res}^3 cells"));
    }
    let values = r.tensor("region.cells", &shape)?;
    let what = if indexed { "cell index" } else { "cell coordinate" };
    let below = if indexed { (res as u64).pow(3) } else { res as u64 };
    let mut whole = Vec::with_capacity(values.len());
    for (i, &v) in values.iter().enumerate() {
        if !(v.is_finite() && v >= 0.0 && v.fract() == 0.0 && (v as u64) < below) {
            return Err(format!("tensor 'region.cells' holds {v} at {i}, not a {what} of the {res}^3 grid"));
        }
        whole.push(v as u32);
    }
    let cells = match indexed {
        true => whole,
        false => whole.chunks_exact(3).map(|c| c[0] + res * (c[1] + res * c[2])).collect(),
    };
    let aabb = field.residual().config().aabb;
    ChangeRegion::from_cells(aabb, res, &cells).map_err(|e| format!("tensor 'region.cells': {e}"))
}

/// The finest change region a model file stores as cell indices (f32, exact up to 2^24); a
/// finer one is stored as its cells' coordinates.
const INDEXED_REGION: u32 = 256;

/// Loads a model of either kind; errors name the file.
pub fn load_model(path: &Path) -> Result<LoadedModel, Error> {
    let bytes = read_model_bytes(path)?;
    model_from_bytes(&bytes).map_err(|e| e.context(path.display()))
}
