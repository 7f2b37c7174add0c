//! Figures: PNG previews of images ([`raster`]: a small raster of our own with colour maps and
//! colour bars), line plots and images on labelled axes ([`plot`]), and their axis ticks
//! ([`ticks`]).

pub mod plot;
pub mod raster;
pub mod ticks;
