//! A user's vehicle model: a Wavefront OBJ file (`tobj`) or a glTF 2.0
//! file (`gltf`: `.gltf` with its `.bin` beside it, or `.glb`), its
//! triangles scaled onto the vehicle's box and rasterised into the bowl's
//! picture with a depth buffer, lit as the built-in model is.
//!
//! Axes of the files:
//! - OBJ: y up; the vehicle's front along −z and its right along +x
//!   (OpenGL's camera looking at the vehicle from behind).
//! - glTF: its specification's, y up, the asset's front along +z and its
//!   right along −x; the default scene's node transforms apply.
//!
//! The model's bounding box is scaled onto the vehicle's rectangle and
//! height, each axis on its own, so that it covers the blind area
//! whatever its proportions.

use std::path::Path;

use nalgebra::Vector3;

use super::vehicle::{shade, BODY};
use super::VirtualCamera;
use crate::error::{Error, Result};

/// The most triangles a model may have (a few hundred thousand render in
/// a fraction of a second; more is a scan, not a vehicle model).
const MAX_TRIANGLES: usize = 2_000_000;

/// A triangle (vehicle frame) and its colour (linear RGB, 0–1).
type Triangle = ([Vector3<f64>; 3], [f64; 3]);

/// A triangle mesh in the vehicle frame with a colour per triangle.
#[derive(Clone, Debug)]
pub struct Mesh {
    triangles: Vec<Triangle>,
}

impl Mesh {
    /// Loads the model at `path`: glTF for `.gltf` and `.glb`, OBJ
    /// otherwise ([`Mesh::load_obj`], [`Mesh::load_gltf`]).
    pub fn load(path: &Path, rect: [f64; 4], height_m: f64) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("gltf" | "glb") => Self::load_gltf(path, rect, height_m),
            _ => Self::load_obj(path, rect, height_m),
        }
    }

    /// Loads the glTF 2.0 file at `path` (`.gltf` with its buffers in
    /// files beside it, or `.glb`): the triangles of its default scene
    /// (or its first), placed by their nodes' transforms, in their
    /// materials' base colours; then scales it onto `rect` and `height_m`
    /// as [`Mesh::load_obj`] does.
    pub fn load_gltf(path: &Path, rect: [f64; 4], height_m: f64) -> Result<Self> {
        let what = format!("vehicle model {}", path.display());
        let raw = read_gltf(path, &what)?;
        Self::placed(what, raw, rect, height_m)
    }

    /// Loads the OBJ file at `path` (its materials' diffuse colours where
    /// it has them) and scales it onto `rect` (`[x_min, x_max, y_min,
    /// y_max]`, metres) and `height_m`.
    pub fn load_obj(path: &Path, rect: [f64; 4], height_m: f64) -> Result<Self> {
        let what = format!("vehicle model {}", path.display());
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..tobj::LoadOptions::default()
        };
        let (models, materials) = tobj::load_obj(path, &options).map_err(|e| {
            Error::invalid(
                what.clone(),
                "its contents",
                "a Wavefront OBJ file of triangles or polygons",
                e,
            )
        })?;
        let colours: Vec<[f64; 3]> = materials
            .unwrap_or_default()
            .iter()
            .map(|m| m.diffuse.map_or(BODY, |d| d.map(f64::from)))
            .collect();
        let mut raw = Vec::new();
        for m in &models {
            let mesh = &m.mesh;
            let colour = mesh
                .material_id
                .and_then(|i| colours.get(i).copied())
                .unwrap_or(BODY);
            let vertex = |i: u32| -> Option<Vector3<f64>> {
                let k = 3 * i as usize;
                let p = mesh.positions.get(k..k + 3)?;
                // OBJ (x right, y up, z back) to the vehicle frame (x
                // forward, y left, z up).
                Some(Vector3::new(
                    -f64::from(p[2]),
                    -f64::from(p[0]),
                    f64::from(p[1]),
                ))
            };
            for tri in mesh.indices.chunks_exact(3) {
                let (Some(a), Some(b), Some(c)) = (vertex(tri[0]), vertex(tri[1]), vertex(tri[2]))
                else {
                    return Err(Error::invalid(
                        what,
                        format!("model `{}`'s faces", m.name),
                        "vertex indices within its vertices",
                        format_args!("{:?}", tri),
                    ));
                };
                raw.push(([a, b, c], colour));
            }
        }
        Self::placed(what, raw, rect, height_m)
    }

    /// Triangles in the vehicle frame's axes, scaled onto `rect` and
    /// `height_m`.
    fn placed(what: String, raw: Vec<Triangle>, rect: [f64; 4], height_m: f64) -> Result<Self> {
        if raw.is_empty() || raw.len() > MAX_TRIANGLES {
            return Err(Error::invalid(
                what,
                "its faces",
                format!("1 to {MAX_TRIANGLES} triangles"),
                raw.len(),
            ));
        }
        let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
        for (t, _) in &raw {
            for p in t {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
        }
        let size = hi - lo;
        if !size.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(Error::invalid(
                what,
                "its vertices",
                "a model with an extent in every axis",
                format_args!("an extent of {:.3} × {:.3} × {:.3}", size.x, size.y, size.z),
            ));
        }
        let [x0, x1, y0, y1] = rect;
        let target_lo = Vector3::new(x0, y0, 0.0);
        let target = Vector3::new(x1 - x0, y1 - y0, height_m);
        let place =
            |p: &Vector3<f64>| target_lo + (p - lo).component_div(&size).component_mul(&target);
        Ok(Self {
            triangles: raw
                .iter()
                .map(|(t, c)| ([place(&t[0]), place(&t[1]), place(&t[2])], *c))
                .collect(),
        })
    }

    /// The triangles (vehicle frame, metres) and their colours (linear
    /// RGB, 0–1).
    pub fn triangles(&self) -> &[([Vector3<f64>; 3], [f64; 3])] {
        &self.triangles
    }

    /// The number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether it has none (never, once loaded).
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Rasterises the mesh into a `w × h` picture seen by `camera`, at
    /// 2 × 2 samples a pixel: per pixel the mean colour of the samples it
    /// covers (RGB) and their share (0 to 1), row-major.
    pub fn rasterise(&self, camera: &VirtualCamera, w: usize, h: usize) -> Vec<([f64; 3], f64)> {
        let (sw, sh) = (2 * w, 2 * h);
        let mut depth = vec![f64::INFINITY; sw * sh];
        let mut colour = vec![[0.0; 3]; sw * sh];
        for ([a, b, c], base) in &self.triangles {
            let project = |p: &Vector3<f64>| {
                let d = p - camera.eye;
                let z = d.dot(&camera.forward);
                let (col, row) = camera.project(p)?;
                Some((2.0 * col, 2.0 * row, z))
            };
            // Triangles with a corner behind the eye are left out.
            let (Some(pa), Some(pb), Some(pc)) = (project(a), project(b), project(c)) else {
                continue;
            };
            let normal = (b - a).cross(&(c - a));
            if normal.norm() == 0.0 {
                continue;
            }
            let rgb = shade(*base, &normal.normalize(), &(a - camera.eye));
            let area = (pb.0 - pa.0) * (pc.1 - pa.1) - (pc.0 - pa.0) * (pb.1 - pa.1);
            if area.abs() < 1e-12 {
                continue;
            }
            let c0 = pa.0.min(pb.0).min(pc.0).floor().max(0.0) as usize;
            let c1 = (pa.0.max(pb.0).max(pc.0).ceil().max(0.0) as usize).min(sw);
            let r0 = pa.1.min(pb.1).min(pc.1).floor().max(0.0) as usize;
            let r1 = (pa.1.max(pb.1).max(pc.1).ceil().max(0.0) as usize).min(sh);
            for r in r0..r1 {
                for col in c0..c1 {
                    let (x, y) = (col as f64 + 0.5, r as f64 + 0.5);
                    let wa = ((pb.0 - x) * (pc.1 - y) - (pc.0 - x) * (pb.1 - y)) / area;
                    let wb = ((pc.0 - x) * (pa.1 - y) - (pa.0 - x) * (pc.1 - y)) / area;
                    let wc = 1.0 - wa - wb;
                    if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                        continue;
                    }
                    // Depth along the axis, interpolated in 1/z.
                    let z = 1.0 / (wa / pa.2 + wb / pb.2 + wc / pc.2);
                    let i = r * sw + col;
                    if z < depth[i] {
                        depth[i] = z;
                        colour[i] = rgb;
                    }
                }
            }
        }
        let mut out = vec![([0.0; 3], 0.0); w * h];
        for (i, px) in out.iter_mut().enumerate() {
            let (c, r) = (i % w, i / w);
            let mut n = 0.0;
            let mut sum = [0.0; 3];
            for (dc, dr) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let j = (2 * r + dr) * sw + 2 * c + dc;
                if depth[j].is_finite() {
                    n += 1.0;
                    for k in 0..3 {
                        sum[k] += colour[j][k];
                    }
                }
            }
            if n > 0.0 {
                *px = (sum.map(|s| s / n), n / 4.0);
            }
        }
        out
    }
}

/// The triangles of the glTF file at `path`, in the vehicle frame's axes
/// (unscaled), each in its material's base colour.
fn read_gltf(path: &Path, what: &str) -> Result<Vec<Triangle>> {
    let invalid = |field: String, expected: &str, found: &dyn std::fmt::Display| {
        Error::invalid(what.to_owned(), field, expected.to_owned(), found)
    };
    let bytes = std::fs::read(path).map_err(|e| {
        invalid(
            "the file".into(),
            "a readable glTF file (.gltf or .glb)",
            &e,
        )
    })?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| {
        invalid(
            "its contents".into(),
            "glTF 2.0 (JSON .gltf or binary .glb)",
            &e,
        )
    })?;
    let dir = path.parent().unwrap_or_else(|| Path::new("."));
    let mut buffers = Vec::new();
    for b in gltf.buffers() {
        let field = format!("buffer {}", b.index());
        let data = match b.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                invalid(
                    field.clone(),
                    "the .glb's binary chunk",
                    &"a file without one",
                )
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                return Err(invalid(
                    field,
                    "a .bin file beside it, or a .glb (embedded base64 buffers are not read)",
                    &"a data: URI",
                ));
            }
            gltf::buffer::Source::Uri(uri) => {
                let file = dir.join(uri);
                std::fs::read(&file).map_err(|e| {
                    invalid(
                        field.clone(),
                        "its file, readable",
                        &format_args!("{}: {e}", file.display()),
                    )
                })?
            }
        };
        if data.len() < b.length() {
            return Err(invalid(
                field,
                &format!("{} bytes", b.length()),
                &format_args!("{} bytes", data.len()),
            ));
        }
        buffers.push(data);
    }
    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or_else(|| invalid("its scenes".into(), "at least one", &0))?;
    let mut raw = Vec::new();
    let mut stack: Vec<(gltf::Node<'_>, nalgebra::Matrix4<f64>)> = scene
        .nodes()
        .map(|n| (n, nalgebra::Matrix4::identity()))
        .collect();
    while let Some((node, parent)) = stack.pop() {
        let local = node.transform().matrix();
        let m = parent * nalgebra::Matrix4::from_fn(|r, c| f64::from(local[c][r]));
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                let field = || format!("mesh {}'s primitive {}", mesh.index(), prim.index());
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    return Err(invalid(
                        field(),
                        "triangles",
                        &format_args!("{:?}", prim.mode()),
                    ));
                }
                let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
                let positions: Vec<[f32; 3]> = reader
                    .read_positions()
                    .ok_or_else(|| invalid(field(), "vertex positions", &"none"))?
                    .collect();
                let indices: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..positions.len() as u32).collect(),
                };
                let material = prim.material();
                let colour = match material.index() {
                    Some(_) => {
                        let [r, g, b, _] = material.pbr_metallic_roughness().base_color_factor();
                        [r, g, b].map(f64::from)
                    }
                    None => BODY,
                };
                let vertex = |i: u32| -> Option<Vector3<f64>> {
                    let p = positions.get(i as usize)?;
                    let q = m * nalgebra::Vector4::new(
                        f64::from(p[0]),
                        f64::from(p[1]),
                        f64::from(p[2]),
                        1.0,
                    );
                    // glTF (x left of the asset, y up, z its front) to the
                    // vehicle frame (x forward, y left, z up).
                    Some(Vector3::new(q.z, q.x, q.y))
                };
                for tri in indices.chunks_exact(3) {
                    let (Some(a), Some(b), Some(c)) =
                        (vertex(tri[0]), vertex(tri[1]), vertex(tri[2]))
                    else {
                        return Err(invalid(
                            field(),
                            "vertex indices within its vertices",
                            &format_args!("{tri:?}"),
                        ));
                    };
                    raw.push(([a, b, c], colour));
                    if raw.len() > MAX_TRIANGLES {
                        return Err(invalid(
                            "its faces".into(),
                            &format!("1 to {MAX_TRIANGLES} triangles"),
                            &format_args!("more than {MAX_TRIANGLES}"),
                        ));
                    }
                }
            }
        }
        stack.extend(node.children().map(|c| (c, m)));
    }
    Ok(raw)
}
