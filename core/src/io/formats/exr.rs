//! OpenEXR images of `f32` channels.

/// An EXR image of named `f32` channels (`ny` rows of `nx`), as bytes.
pub fn exr_bytes(nx: usize, ny: usize, channels: &[(&str, &[f64])]) -> std::result::Result<Vec<u8>, String> {
    use ::exr::prelude::*;
    let list: Vec<AnyChannel<FlatSamples>> = channels
        .iter()
        .map(|(name, data)| AnyChannel::new(*name, FlatSamples::F32(data.iter().map(|&v| v as f32).collect())))
        .collect();
    let layer = Layer::new(
        (nx, ny),
        LayerAttributes::named("ohd"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    let mut cursor = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut cursor).map_err(|e| e.to_string())?;
    Ok(cursor.into_inner())
}
