//! The bowl on the GPU (OpenGL 3.3 or OpenGL ES 3.0, through `glow`):
//! the surface mesh of [`SurfaceMesh`] with the camera frames as textures,
//! each fragment weighing the cameras as the CPU's maps do, and the
//! vehicle's lit triangles over it. It draws into a framebuffer of its own
//! (colour and depth), which the window blits into its view and the tests
//! read back.
//!
//! A new viewpoint is a new matrix: orbiting costs no rebuild. Each new
//! frame set uploads the four frames once (`glTexSubImage2D` of 8-bit
//! grey or RGB, the rows as they come: no conversion on the UI thread).
//!
//! Every GL call is `unsafe` in `glow`; the module allows it, and each
//! block says what it relies on.
#![allow(unsafe_code)]

use eframe::glow::{self, HasContext};
use khronos_egl as egl;
use rigview_core::bowl::{SurfaceMesh, VehicleTriangles, VirtualCamera, MAX_GPU_CAMERAS};
use rigview_core::surround::BlendMode;

/// The near and far planes, metres.
const NEAR_FAR: (f32, f32) = (0.1, 400.0);

const SURFACE_VS: &str = r#"
uniform mat4 u_view_proj;
in vec3 a_pos;
in vec4 a_src01;
in vec4 a_src23;
in vec4 a_dist;
in vec4 a_beyond;
out vec4 v_src01;
out vec4 v_src23;
out vec4 v_dist;
out vec4 v_beyond;
void main() {
    v_src01 = a_src01;
    v_src23 = a_src23;
    v_dist = a_dist;
    v_beyond = a_beyond;
    gl_Position = u_view_proj * vec4(a_pos, 1.0);
}
"#;

const SURFACE_FS: &str = r#"
uniform sampler2D u_tex0;
uniform sampler2D u_tex1;
uniform sampler2D u_tex2;
uniform sampler2D u_tex3;
// Per camera: image width and height.
uniform vec4 u_size01;
uniform vec4 u_size23;
// Per camera: 1 for a grey frame.
uniform vec4 u_grey;
// Per camera: the exposure gain (clipped at white) and the seam gain.
uniform vec4 u_exposure;
uniform vec4 u_seam;
// 0 linear, 1 alpha, 2 seams.
uniform int u_mode;
in vec4 v_src01;
in vec4 v_src23;
in vec4 v_dist;
in vec4 v_beyond;
out vec4 o_colour;

float sees(vec2 src, vec2 size, float beyond) {
    return (beyond > 0.0 && src.x >= 0.0 && src.y >= 0.0
        && src.x <= size.x - 1.0 && src.y <= size.y - 1.0) ? 1.0 : 0.0;
}

vec3 fetch(sampler2D t, vec2 src, vec2 size, float grey) {
    vec4 c = texture(t, (src + 0.5) / size);
    return grey > 0.5 ? c.rrr : c.rgb;
}

void main() {
    vec4 seen = vec4(
        sees(v_src01.xy, u_size01.xy, v_beyond.x),
        sees(v_src01.zw, u_size01.zw, v_beyond.y),
        sees(v_src23.xy, u_size23.xy, v_beyond.z),
        sees(v_src23.zw, u_size23.zw, v_beyond.w));
    float count = dot(seen, vec4(1.0));
    if (count < 0.5) {
        o_colour = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec4 d = max(v_dist, vec4(0.5));
    vec4 inv = seen / (d * d);
    vec4 w;
    if (u_mode == 1) {
        w = seen / count;
    } else if (u_mode == 2) {
        // The last camera of the largest weight.
        float best = max(max(inv.x, inv.y), max(inv.z, inv.w));
        vec4 is_best = vec4(greaterThanEqual(inv, vec4(best))) * seen;
        if (is_best.w > 0.5) { w = vec4(0.0, 0.0, 0.0, 1.0); }
        else if (is_best.z > 0.5) { w = vec4(0.0, 0.0, 1.0, 0.0); }
        else if (is_best.y > 0.5) { w = vec4(0.0, 1.0, 0.0, 0.0); }
        else { w = vec4(1.0, 0.0, 0.0, 0.0); }
    } else {
        w = inv / dot(inv, vec4(1.0));
    }
    vec3 c = vec3(0.0);
    if (w.x > 0.0) {
        c += w.x * u_seam.x * min(fetch(u_tex0, v_src01.xy, u_size01.xy, u_grey.x) * u_exposure.x, vec3(1.0));
    }
    if (w.y > 0.0) {
        c += w.y * u_seam.y * min(fetch(u_tex1, v_src01.zw, u_size01.zw, u_grey.y) * u_exposure.y, vec3(1.0));
    }
    if (w.z > 0.0) {
        c += w.z * u_seam.z * min(fetch(u_tex2, v_src23.xy, u_size23.xy, u_grey.z) * u_exposure.z, vec3(1.0));
    }
    if (w.w > 0.0) {
        c += w.w * u_seam.w * min(fetch(u_tex3, v_src23.zw, u_size23.zw, u_grey.w) * u_exposure.w, vec3(1.0));
    }
    o_colour = vec4(clamp(c, 0.0, 1.0), 1.0);
}
"#;

const VEHICLE_VS: &str = r#"
uniform mat4 u_view_proj;
in vec3 a_pos;
in vec3 a_normal;
in vec4 a_rgba;
out vec3 v_pos;
out vec3 v_normal;
out vec4 v_rgba;
void main() {
    v_pos = a_pos;
    v_normal = a_normal;
    v_rgba = a_rgba;
    gl_Position = u_view_proj * vec4(a_pos, 1.0);
}
"#;

// The built-in model's light (see rigview_core's bowl::vehicle::shade):
// one light from above, ahead and to the left, some from all round, either
// side of a face lit alike; a normal of zero is unlit (the shadow).
const VEHICLE_FS: &str = r#"
uniform vec3 u_eye;
in vec3 v_pos;
in vec3 v_normal;
in vec4 v_rgba;
out vec4 o_colour;
void main() {
    if (dot(v_normal, v_normal) < 0.5) {
        o_colour = v_rgba;
        return;
    }
    vec3 light = normalize(vec3(0.35, 0.25, 1.0));
    vec3 n = normalize(v_normal);
    vec3 facing = dot(n, v_pos - u_eye) > 0.0 ? -n : n;
    float lit = 0.4 + 0.6 * max(dot(facing, light), 0.0);
    o_colour = vec4(pow(clamp(v_rgba.rgb * lit, 0.0, 1.0), vec3(1.0 / 2.2)), v_rgba.a);
}
"#;

/// One camera's frame for the GPU: 8-bit grey or RGB rows, tightly
/// packed.
#[derive(Clone, Copy, Debug)]
pub struct TextureFrame<'a> {
    pub width: usize,
    pub height: usize,
    /// 1 (grey) or 3 (RGB).
    pub channels: usize,
    pub data: &'a [u8],
}

impl<'a> TextureFrame<'a> {
    /// An RGB image's pixels.
    pub fn rgb(image: &'a image::RgbImage) -> Self {
        Self {
            width: image.width() as usize,
            height: image.height() as usize,
            channels: 3,
            data: image.as_raw(),
        }
    }
}

/// Each camera's gains for the display: the exposure gain (applied first,
/// clipped at white, as the CPU scales a frame shown at another exposure)
/// and the seam gain.
pub type CameraGains = [f32; 2];

/// A camera's texture and its width, height and channels.
type CameraTexture = (glow::Texture, (usize, usize, usize));

/// The GL objects of the bowl.
#[derive(Debug)]
pub struct BowlGl {
    surface: Program,
    vehicle: Program,
    surface_vao: glow::VertexArray,
    surface_buffers: [glow::Buffer; 2],
    surface_count: i32,
    vehicle_vao: glow::VertexArray,
    vehicle_buffer: glow::Buffer,
    vehicle_count: i32,
    /// Two sets of textures, per camera the texture and its size and
    /// channels: a new frame set goes into the set not drawn last, so that
    /// its upload need not wait for a draw still under way.
    textures: [Vec<CameraTexture>; 2],
    /// The set drawn from.
    current: usize,
    /// The framebuffer drawn into: it, its colour and depth, its size.
    target: Option<(
        glow::Framebuffer,
        glow::Renderbuffer,
        glow::Renderbuffer,
        (i32, i32),
    )>,
}

/// A linked program and its uniforms' locations by name.
#[derive(Debug)]
struct Program {
    program: glow::Program,
}

impl Program {
    fn new(gl: &glow::Context, vs: &str, fs: &str, attributes: &[&str]) -> Result<Self, String> {
        let header = if gl.version().is_embedded {
            "#version 300 es\nprecision highp float;\nprecision highp int;\n"
        } else {
            "#version 330 core\n"
        };
        // SAFETY: plain GL calls on the current context; every object
        // created here is deleted on failure or with the program.
        unsafe {
            let program = gl.create_program()?;
            let mut shaders = Vec::new();
            for (kind, source) in [(glow::VERTEX_SHADER, vs), (glow::FRAGMENT_SHADER, fs)] {
                let shader = gl.create_shader(kind)?;
                gl.shader_source(shader, &format!("{header}{source}"));
                gl.compile_shader(shader);
                if !gl.get_shader_compile_status(shader) {
                    let log = gl.get_shader_info_log(shader);
                    gl.delete_shader(shader);
                    gl.delete_program(program);
                    return Err(format!("the bowl's shader does not compile: {log}"));
                }
                gl.attach_shader(program, shader);
                shaders.push(shader);
            }
            for (i, name) in attributes.iter().enumerate() {
                gl.bind_attrib_location(program, i as u32, name);
            }
            gl.link_program(program);
            for s in shaders {
                gl.detach_shader(program, s);
                gl.delete_shader(s);
            }
            if !gl.get_program_link_status(program) {
                let log = gl.get_program_info_log(program);
                gl.delete_program(program);
                return Err(format!("the bowl's shaders do not link: {log}"));
            }
            Ok(Self { program })
        }
    }

    fn uniform(&self, gl: &glow::Context, name: &str) -> Option<glow::UniformLocation> {
        // SAFETY: a query on a linked program.
        unsafe { gl.get_uniform_location(self.program, name) }
    }
}

/// Where the bowl is drawn from and how.
#[derive(Clone, Debug)]
pub struct Shot {
    /// The viewpoint's camera for a picture of `size`.
    pub camera: VirtualCamera,
    /// The picture's width and height, pixels.
    pub size: (usize, usize),
    pub gains: Vec<CameraGains>,
    pub mode: BlendMode,
}

impl BowlGl {
    /// Compiles the shaders and makes the buffers, on the current context.
    pub fn new(gl: &glow::Context) -> Result<Self, String> {
        let surface = Program::new(
            gl,
            SURFACE_VS,
            SURFACE_FS,
            &["a_pos", "a_src01", "a_src23", "a_dist", "a_beyond"],
        )?;
        let vehicle = Program::new(gl, VEHICLE_VS, VEHICLE_FS, &["a_pos", "a_normal", "a_rgba"])?;
        // SAFETY: object creation on the current context.
        unsafe {
            Ok(Self {
                surface,
                vehicle,
                surface_vao: gl.create_vertex_array()?,
                surface_buffers: [gl.create_buffer()?, gl.create_buffer()?],
                surface_count: 0,
                vehicle_vao: gl.create_vertex_array()?,
                vehicle_buffer: gl.create_buffer()?,
                vehicle_count: 0,
                textures: [Vec::new(), Vec::new()],
                current: 0,
                target: None,
            })
        }
    }

    /// Takes the bowl's surface and vehicle (a new bowl or rig).
    pub fn set_geometry(&mut self, gl: &glow::Context, mesh: &SurfaceMesh, car: &VehicleTriangles) {
        let floats: Vec<f32> = mesh
            .vertices
            .iter()
            .flat_map(|v| {
                let mut out = Vec::with_capacity(19);
                out.extend_from_slice(&v.position);
                for s in &v.source {
                    out.extend_from_slice(s);
                }
                out.extend_from_slice(&v.distance);
                out.extend_from_slice(&v.beyond);
                out
            })
            .collect();
        let car_floats: Vec<f32> = car
            .vertices
            .iter()
            .flat_map(|(p, n, c)| p.iter().chain(n).chain(c).copied().collect::<Vec<_>>())
            .collect();
        // SAFETY: buffers and arrays this renderer made, on the current
        // context; the attribute layouts match the data written.
        unsafe {
            gl.bind_vertex_array(Some(self.surface_vao));
            gl.bind_buffer(glow::ARRAY_BUFFER, Some(self.surface_buffers[0]));
            gl.buffer_data_u8_slice(
                glow::ARRAY_BUFFER,
                &bytes_of_f32(&floats),
                glow::STATIC_DRAW,
            );
            let stride = 19 * 4;
            for (i, (size, offset)) in [(3, 0), (4, 3), (4, 7), (4, 11), (4, 15)]
                .into_iter()
                .enumerate()
            {
                gl.enable_vertex_attrib_array(i as u32);
                gl.vertex_attrib_pointer_f32(
                    i as u32,
                    size,
                    glow::FLOAT,
                    false,
                    stride,
                    offset * 4,
                );
            }
            gl.bind_buffer(glow::ELEMENT_ARRAY_BUFFER, Some(self.surface_buffers[1]));
            let index_bytes: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_ne_bytes()).collect();
            gl.buffer_data_u8_slice(glow::ELEMENT_ARRAY_BUFFER, &index_bytes, glow::STATIC_DRAW);
            self.surface_count = mesh.indices.len() as i32;

            gl.bind_vertex_array(Some(self.vehicle_vao));
            gl.bind_buffer(glow::ARRAY_BUFFER, Some(self.vehicle_buffer));
            gl.buffer_data_u8_slice(
                glow::ARRAY_BUFFER,
                &bytes_of_f32(&car_floats),
                glow::STATIC_DRAW,
            );
            let stride = 10 * 4;
            for (i, (size, offset)) in [(3, 0), (3, 3), (4, 6)].into_iter().enumerate() {
                gl.enable_vertex_attrib_array(i as u32);
                gl.vertex_attrib_pointer_f32(
                    i as u32,
                    size,
                    glow::FLOAT,
                    false,
                    stride,
                    offset * 4,
                );
            }
            self.vehicle_count = car.vertices.len() as i32;
            gl.bind_vertex_array(None);
            gl.bind_buffer(glow::ARRAY_BUFFER, None);
        }
    }

    /// Uploads a frame set (rig order; 8-bit grey or RGB).
    pub fn upload(
        &mut self,
        gl: &glow::Context,
        frames: &[TextureFrame<'_>],
    ) -> Result<(), String> {
        if frames.len() > MAX_GPU_CAMERAS {
            return Err(format!(
                "the GPU's bowl shows at most {MAX_GPU_CAMERAS} cameras, not {}",
                frames.len()
            ));
        }
        let next = 1 - self.current;
        let textures = &mut self.textures[next];
        // SAFETY: textures this renderer made, sized before their data is
        // written; each frame's data is checked against its size.
        unsafe {
            gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 1);
            for (k, f) in frames.iter().enumerate() {
                if !matches!(f.channels, 1 | 3) || f.data.len() != f.width * f.height * f.channels {
                    return Err(format!(
                        "camera {k}'s frame: {}×{} with {} channels and {} bytes",
                        f.width,
                        f.height,
                        f.channels,
                        f.data.len()
                    ));
                }
                let shape = (f.width, f.height, f.channels);
                let (internal, format) = if f.channels == 1 {
                    (glow::R8, glow::RED)
                } else {
                    (glow::RGB8, glow::RGB)
                };
                if textures.len() <= k {
                    let t = gl.create_texture()?;
                    textures.push((t, (0, 0, 0)));
                }
                let (texture, had) = &mut textures[k];
                gl.bind_texture(glow::TEXTURE_2D, Some(*texture));
                if *had != shape {
                    gl.tex_image_2d(
                        glow::TEXTURE_2D,
                        0,
                        internal as i32,
                        f.width as i32,
                        f.height as i32,
                        0,
                        format,
                        glow::UNSIGNED_BYTE,
                        glow::PixelUnpackData::Slice(None),
                    );
                    for (p, v) in [
                        (glow::TEXTURE_MIN_FILTER, glow::LINEAR),
                        (glow::TEXTURE_MAG_FILTER, glow::LINEAR),
                        (glow::TEXTURE_WRAP_S, glow::CLAMP_TO_EDGE),
                        (glow::TEXTURE_WRAP_T, glow::CLAMP_TO_EDGE),
                    ] {
                        gl.tex_parameter_i32(glow::TEXTURE_2D, p, v as i32);
                    }
                    *had = shape;
                }
                gl.tex_sub_image_2d(
                    glow::TEXTURE_2D,
                    0,
                    0,
                    0,
                    f.width as i32,
                    f.height as i32,
                    format,
                    glow::UNSIGNED_BYTE,
                    glow::PixelUnpackData::Slice(Some(f.data)),
                );
            }
            gl.bind_texture(glow::TEXTURE_2D, None);
        }
        self.current = next;
        Ok(())
    }

    /// Draws the bowl as `shot` says into the renderer's framebuffer
    /// (which stays bound for reading when this returns).
    pub fn draw(&mut self, gl: &glow::Context, shot: &Shot) -> Result<(), String> {
        let (w, h) = (shot.size.0.max(1) as i32, shot.size.1.max(1) as i32);
        self.ensure_target(gl, (w, h))?;
        let Some((fbo, ..)) = self.target else {
            return Err("no framebuffer".into());
        };
        let view_proj = view_projection(&shot.camera, shot.size);
        let mut sizes = [1.0f32; 8];
        let mut grey = [1.0f32; 4];
        let mut exposure = [1.0f32; 4];
        let mut seam = [1.0f32; 4];
        let textures = &self.textures[self.current];
        for (k, (_, (tw, th, ch))) in textures.iter().enumerate().take(MAX_GPU_CAMERAS) {
            sizes[2 * k] = *tw as f32;
            sizes[2 * k + 1] = *th as f32;
            grey[k] = if *ch == 1 { 1.0 } else { 0.0 };
        }
        for (k, g) in shot.gains.iter().enumerate().take(MAX_GPU_CAMERAS) {
            exposure[k] = g[0];
            seam[k] = g[1];
        }
        let mode = match shot.mode {
            BlendMode::Linear => 0,
            BlendMode::Alpha => 1,
            BlendMode::Seams => 2,
        };
        // SAFETY: objects this renderer made, on the current context.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(fbo));
            gl.viewport(0, 0, w, h);
            gl.disable(glow::SCISSOR_TEST);
            gl.disable(glow::BLEND);
            gl.clear_color(0.0, 0.0, 0.0, 1.0);
            gl.clear_depth_f32(1.0);
            gl.depth_mask(true);
            gl.clear(glow::COLOR_BUFFER_BIT | glow::DEPTH_BUFFER_BIT);
            gl.enable(glow::DEPTH_TEST);
            gl.depth_func(glow::LEQUAL);
            // The wall seen from outside the rim lets the view through.
            gl.enable(glow::CULL_FACE);
            gl.cull_face(glow::BACK);
            gl.front_face(glow::CCW);

            let p = &self.surface;
            gl.use_program(Some(p.program));
            gl.uniform_matrix_4_f32_slice(p.uniform(gl, "u_view_proj").as_ref(), false, &view_proj);
            for k in 0..MAX_GPU_CAMERAS {
                gl.active_texture(glow::TEXTURE0 + k as u32);
                gl.bind_texture(glow::TEXTURE_2D, textures.get(k).map(|t| t.0));
                gl.uniform_1_i32(p.uniform(gl, &format!("u_tex{k}")).as_ref(), k as i32);
            }
            gl.uniform_4_f32_slice(p.uniform(gl, "u_size01").as_ref(), &sizes[..4]);
            gl.uniform_4_f32_slice(p.uniform(gl, "u_size23").as_ref(), &sizes[4..]);
            gl.uniform_4_f32_slice(p.uniform(gl, "u_grey").as_ref(), &grey);
            gl.uniform_4_f32_slice(p.uniform(gl, "u_exposure").as_ref(), &exposure);
            gl.uniform_4_f32_slice(p.uniform(gl, "u_seam").as_ref(), &seam);
            gl.uniform_1_i32(p.uniform(gl, "u_mode").as_ref(), mode);
            gl.bind_vertex_array(Some(self.surface_vao));
            gl.draw_elements(glow::TRIANGLES, self.surface_count, glow::UNSIGNED_INT, 0);

            gl.disable(glow::CULL_FACE);
            gl.enable(glow::BLEND);
            gl.blend_func_separate(
                glow::SRC_ALPHA,
                glow::ONE_MINUS_SRC_ALPHA,
                glow::ZERO,
                glow::ONE,
            );
            let v = &self.vehicle;
            gl.use_program(Some(v.program));
            gl.uniform_matrix_4_f32_slice(v.uniform(gl, "u_view_proj").as_ref(), false, &view_proj);
            let eye = shot.camera.eye;
            gl.uniform_3_f32(
                v.uniform(gl, "u_eye").as_ref(),
                eye.x as f32,
                eye.y as f32,
                eye.z as f32,
            );
            gl.bind_vertex_array(Some(self.vehicle_vao));
            gl.draw_arrays(glow::TRIANGLES, 0, self.vehicle_count);

            gl.bind_vertex_array(None);
            gl.use_program(None);
            gl.disable(glow::DEPTH_TEST);
            gl.disable(glow::BLEND);
            for k in 0..MAX_GPU_CAMERAS {
                gl.active_texture(glow::TEXTURE0 + k as u32);
                gl.bind_texture(glow::TEXTURE_2D, None);
            }
            gl.active_texture(glow::TEXTURE0);
        }
        Ok(())
    }

    /// Copies the last drawing into `rect` (x, y from the bottom left,
    /// width, height; pixels) of framebuffer `into` (`None`: the default
    /// one).
    pub fn blit(&self, gl: &glow::Context, into: Option<glow::Framebuffer>, rect: [i32; 4]) {
        let Some((fbo, _, _, (w, h))) = self.target else {
            return;
        };
        let [x, y, rw, rh] = rect;
        // SAFETY: framebuffers of this renderer and the caller's.
        unsafe {
            gl.bind_framebuffer(glow::READ_FRAMEBUFFER, Some(fbo));
            gl.bind_framebuffer(glow::DRAW_FRAMEBUFFER, into);
            gl.blit_framebuffer(
                0,
                0,
                w,
                h,
                x,
                y,
                x + rw,
                y + rh,
                glow::COLOR_BUFFER_BIT,
                glow::NEAREST,
            );
            gl.bind_framebuffer(glow::FRAMEBUFFER, into);
        }
    }

    /// Waits until the GPU has done what it was asked.
    pub fn finish(&self, gl: &glow::Context) {
        // SAFETY: a plain GL call on the current context.
        unsafe { gl.finish() }
    }

    /// The last drawing as RGB rows from the top.
    pub fn read_rgb(&self, gl: &glow::Context) -> Option<(usize, usize, Vec<u8>)> {
        let (fbo, _, _, (w, h)) = self.target?;
        let (uw, uh) = (w as usize, h as usize);
        let mut rgba = vec![0u8; uw * uh * 4];
        // SAFETY: reads the renderer's own framebuffer into a buffer of
        // its size.
        unsafe {
            gl.bind_framebuffer(glow::READ_FRAMEBUFFER, Some(fbo));
            gl.pixel_store_i32(glow::PACK_ALIGNMENT, 1);
            gl.read_pixels(
                0,
                0,
                w,
                h,
                glow::RGBA,
                glow::UNSIGNED_BYTE,
                glow::PixelPackData::Slice(Some(&mut rgba)),
            );
        }
        let mut rgb = Vec::with_capacity(uw * uh * 3);
        for r in (0..uh).rev() {
            for px in rgba[r * uw * 4..(r + 1) * uw * 4].chunks_exact(4) {
                rgb.extend_from_slice(&px[..3]);
            }
        }
        Some((uw, uh, rgb))
    }

    fn ensure_target(&mut self, gl: &glow::Context, size: (i32, i32)) -> Result<(), String> {
        if self.target.is_some_and(|t| t.3 == size) {
            return Ok(());
        }
        self.drop_target(gl);
        // SAFETY: new objects on the current context, checked complete.
        unsafe {
            let fbo = gl.create_framebuffer()?;
            let colour = gl.create_renderbuffer()?;
            let depth = gl.create_renderbuffer()?;
            gl.bind_renderbuffer(glow::RENDERBUFFER, Some(colour));
            gl.renderbuffer_storage(glow::RENDERBUFFER, glow::RGBA8, size.0, size.1);
            gl.bind_renderbuffer(glow::RENDERBUFFER, Some(depth));
            gl.renderbuffer_storage(glow::RENDERBUFFER, glow::DEPTH_COMPONENT24, size.0, size.1);
            gl.bind_renderbuffer(glow::RENDERBUFFER, None);
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(fbo));
            gl.framebuffer_renderbuffer(
                glow::FRAMEBUFFER,
                glow::COLOR_ATTACHMENT0,
                glow::RENDERBUFFER,
                Some(colour),
            );
            gl.framebuffer_renderbuffer(
                glow::FRAMEBUFFER,
                glow::DEPTH_ATTACHMENT,
                glow::RENDERBUFFER,
                Some(depth),
            );
            let status = gl.check_framebuffer_status(glow::FRAMEBUFFER);
            self.target = Some((fbo, colour, depth, size));
            if status != glow::FRAMEBUFFER_COMPLETE {
                self.drop_target(gl);
                return Err(format!(
                    "the bowl's framebuffer is incomplete ({status:#x})"
                ));
            }
        }
        Ok(())
    }

    fn drop_target(&mut self, gl: &glow::Context) {
        if let Some((fbo, colour, depth, _)) = self.target.take() {
            // SAFETY: objects of this renderer, no longer used.
            unsafe {
                gl.delete_framebuffer(fbo);
                gl.delete_renderbuffer(colour);
                gl.delete_renderbuffer(depth);
            }
        }
    }

    /// Deletes every GL object of the renderer.
    pub fn destroy(mut self, gl: &glow::Context) {
        self.drop_target(gl);
        // SAFETY: objects of this renderer, no longer used.
        unsafe {
            gl.delete_program(self.surface.program);
            gl.delete_program(self.vehicle.program);
            gl.delete_vertex_array(self.surface_vao);
            gl.delete_vertex_array(self.vehicle_vao);
            for b in self.surface_buffers {
                gl.delete_buffer(b);
            }
            gl.delete_buffer(self.vehicle_buffer);
            for (t, _) in self.textures.into_iter().flatten() {
                gl.delete_texture(t);
            }
        }
    }
}

/// The column-major view-projection matrix of `camera` for a picture of
/// `size`: the pinhole's pixels exactly (its principal point and focal
/// length), y up in clip space.
pub fn view_projection(camera: &VirtualCamera, (w, h): (usize, usize)) -> [f32; 16] {
    let (w, h) = (w.max(1) as f64, h.max(1) as f64);
    let (n, f) = (f64::from(NEAR_FAR.0), f64::from(NEAR_FAR.1));
    let (r, u, fw) = (camera.right, camera.up, camera.forward);
    let e = camera.eye;
    // Eye space: x right, y up, z backwards.
    let view = [
        [r.x, r.y, r.z, -r.dot(&e)],
        [u.x, u.y, u.z, -u.dot(&e)],
        [-fw.x, -fw.y, -fw.z, fw.dot(&e)],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let (cx, cy) = camera.centre;
    let proj = [
        [2.0 * camera.focal / w, 0.0, 1.0 - 2.0 * cx / w, 0.0],
        [0.0, 2.0 * camera.focal / h, 2.0 * cy / h - 1.0, 0.0],
        [0.0, 0.0, -(f + n) / (f - n), -2.0 * f * n / (f - n)],
        [0.0, 0.0, -1.0, 0.0],
    ];
    let mut out = [0.0f32; 16];
    for row in 0..4 {
        for col in 0..4 {
            let v: f64 = (0..4).map(|k| proj[row][k] * view[k][col]).sum();
            out[col * 4 + row] = v as f32;
        }
    }
    out
}

fn bytes_of_f32(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|f| f.to_ne_bytes()).collect()
}

/// EGL's platform of no display (Mesa's).
const PLATFORM_SURFACELESS_MESA: egl::Enum = 0x31DD;

/// An OpenGL 3.3 core context with no display or window (Mesa's
/// surfaceless EGL platform: its software renderer here, a GPU's driver
/// where there is one), current on the calling thread for as long as the
/// thread lives: for tests and benchmarks of the renderer.
pub fn headless_context() -> Result<glow::Context, String> {
    let fail =
        |what: &str, e: &dyn std::fmt::Display| format!("a headless OpenGL context: {what}: {e}");
    // SAFETY: loads the system's libEGL and calls it as its API says; the
    // instance is leaked so that the context's functions stay loaded.
    unsafe {
        let egl = egl::DynamicInstance::<egl::EGL1_5>::load_required().map_err(|e| {
            fail(
                "libEGL.so.1 (scripts/setup installs libegl1 and libegl-mesa0)",
                &e,
            )
        })?;
        let egl: &'static _ = Box::leak(Box::new(egl));
        let display = egl
            .get_platform_display(
                PLATFORM_SURFACELESS_MESA,
                egl::DEFAULT_DISPLAY,
                &[egl::ATTRIB_NONE],
            )
            .map_err(|e| fail("Mesa's surfaceless EGL platform", &e))?;
        egl.initialize(display)
            .map_err(|e| fail("EGL's initialisation", &e))?;
        egl.bind_api(egl::OPENGL_API)
            .map_err(|e| fail("desktop OpenGL", &e))?;
        let config = egl
            .choose_first_config(
                display,
                &[
                    egl::SURFACE_TYPE,
                    egl::PBUFFER_BIT,
                    egl::RENDERABLE_TYPE,
                    egl::OPENGL_BIT,
                    egl::NONE,
                ],
            )
            .map_err(|e| fail("an EGL configuration", &e))?
            .ok_or_else(|| fail("an EGL configuration", &"none for OpenGL"))?;
        let context = egl
            .create_context(
                display,
                config,
                None,
                &[
                    egl::CONTEXT_MAJOR_VERSION,
                    3,
                    egl::CONTEXT_MINOR_VERSION,
                    3,
                    egl::CONTEXT_OPENGL_PROFILE_MASK,
                    egl::CONTEXT_OPENGL_CORE_PROFILE_BIT,
                    egl::NONE,
                ],
            )
            .map_err(|e| fail("an OpenGL 3.3 core context", &e))?;
        egl.make_current(display, None, None, Some(context))
            .map_err(|e| fail("making it current", &e))?;
        Ok(glow::Context::from_loader_function(|name| {
            egl.get_proc_address(name)
                .map_or(std::ptr::null(), |f| f as *const std::ffi::c_void)
        }))
    }
}
