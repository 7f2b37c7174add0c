//! PNG encoding of 8-bit RGB rasters (the figures draw them, [`crate::io::figures`]).

/// An 8-bit RGB image of `width × height` pixels (`data` row-major from the top, 3 bytes a
/// pixel) as PNG bytes.
pub fn encode_rgb8(width: u32, height: u32, data: &[u8]) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Balanced);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(data)?;
    writer.finish()?;
    Ok(out)
}
