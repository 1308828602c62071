//! Offscreen capture: render a [`SceneView`] headless and read the pixels back.
//!
//! In: a scene, an image size, a path. Out: an RGBA8 (sRGB) image or a PNG
//! file. Stays true: the readback goes through an explicit staging buffer whose
//! rows are padded to 256 bytes (wgpu's copy alignment) and unpadded on the
//! CPU; no adapter gives [`RenderError::NoAdapter`], never a panic. Works on
//! the software Vulkan driver (`VK_DRIVER_FILES=.../lvp_icd.x86_64.json
//! WGPU_BACKEND=vulkan`).

use super::RenderError;
use super::renderer::Renderer;
use super::scene::SceneView;
use std::path::Path;

/// Bytes per row of a `width`-pixel RGBA8 row in the staging buffer (multiple of 256).
pub fn padded_bytes_per_row(width: u32) -> u32 {
    (width * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
}

/// Copies the offscreen target of `renderer` to the CPU.
pub fn read_offscreen(renderer: &Renderer) -> Result<image::RgbaImage, RenderError> {
    let target = renderer
        .offscreen
        .as_ref()
        .ok_or(RenderError::NoOffscreenTarget)?;
    let (width, height) = target.size;
    let device = renderer.device();
    let bytes_per_row = padded_bytes_per_row(width);
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback staging"),
        size: bytes_per_row as u64 * height as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("readback encoder"),
    });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: &target.texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &staging,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(bytes_per_row),
                rows_per_image: Some(height),
            },
        },
        wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
    );
    renderer.queue().submit([encoder.finish()]);
    let (sender, receiver) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |result| {
        let _ = sender.send(result);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    match receiver.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(RenderError::Readback(e.to_string())),
        Err(_) => return Err(RenderError::Readback("the map callback never ran".into())),
    }
    let mut pixels = Vec::with_capacity((width * height * 4) as usize);
    {
        let mapped = staging
            .get_mapped_range(..)
            .map_err(|e| RenderError::Readback(format!("{e:?}")))?;
        for row in mapped.chunks_exact(bytes_per_row as usize) {
            pixels.extend_from_slice(&row[..(width * 4) as usize]);
        }
    }
    staging.unmap();
    renderer.check_gpu_error()?;
    image::RgbaImage::from_raw(width, height, pixels)
        .ok_or_else(|| RenderError::Readback("pixel count does not match the size".into()))
}

/// Renders `view` headless at `size` and returns the image.
pub fn render_image(view: &SceneView, size: (u32, u32)) -> Result<image::RgbaImage, RenderError> {
    let mut renderer = Renderer::new_offscreen(size)?;
    renderer.render_offscreen(view)?;
    read_offscreen(&renderer)
}

/// Renders `view` headless at `size` (width, height) and writes a PNG to `path`.
/// To render many frames, keep a [`Renderer::new_offscreen`] and call
/// [`Renderer::render_offscreen`] + [`read_offscreen`] per frame instead.
pub fn render_png(view: &SceneView, size: (u32, u32), path: &Path) -> Result<(), RenderError> {
    let image = render_image(view, size)?;
    save_png(&image, path)
}

/// Writes an image as PNG, whole or not at all (encoded in memory, then
/// [`crate::fsio::write_atomic`]), naming the path in the error.
pub fn save_png(image: &image::RgbaImage, path: &Path) -> Result<(), RenderError> {
    let png_error = |message: String| RenderError::Png {
        path: path.to_path_buf(),
        message,
    };
    let mut png = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut png, image::ImageFormat::Png)
        .map_err(|e| png_error(e.to_string()))?;
    crate::fsio::write_atomic(path, png.get_ref()).map_err(|e| png_error(e.source.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_pad_to_256_bytes() {
        assert_eq!(padded_bytes_per_row(64), 256);
        assert_eq!(padded_bytes_per_row(65), 512);
        assert_eq!(padded_bytes_per_row(320), 1280);
        assert_eq!(padded_bytes_per_row(1), 256);
    }
}
