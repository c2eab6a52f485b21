//! A checked [`super::request::SynthRequest`]: what is painted, by which painter, into which
//! files. [`SynthPlan::write`] paints into the files and [`SynthPlan::render`] into memory,
//! through the same band loop ([`crate::maps::Bands`]), so both hold the same values.

use std::path::{Path, PathBuf};

use crate::device::DeviceChoice;
use crate::error::Result;
use crate::fit::TilePainter;
use crate::io::{OutputFormat, VolumeFormat};
use crate::maps::{MapOutput, MapSet, preview};
use crate::synth::{DEFAULT_BAND_PIXELS, Painter};

/// A checked synthesis: what is painted, by what, into which files.
pub struct SynthPlan {
    /// Where the model came from, as commands print it.
    pub model: String,
    /// The output file (a map set writes one file per map beside it).
    pub out: PathBuf,
    pub seed: u64,
    pub device: DeviceChoice,
    /// `--preview`: the material's picture, and the maps it is lit from.
    pub(super) preview: Option<(PathBuf, MapSet)>,
    pub(super) target: Target,
}

pub(super) enum Target {
    Image(ImageTarget),
    Slice {
        painter: Painter,
        origin: [i64; 3],
        shape: [usize; 3],
        image: [usize; 2],
        format: OutputFormat,
        what: String,
    },
    Volume {
        painter: Painter,
        shape: [usize; 3],
        format: VolumeFormat,
        mesh: Option<PathBuf>,
    },
}

/// An image (or a map set's images) of `size` from `origin`, by a trained model or a fitted
/// tile.
pub(super) struct ImageTarget {
    pub painter: ImagePainter,
    pub origin: [i64; 2],
    pub size: [usize; 2],
    pub outputs: Vec<MapOutput>,
    pub names: Vec<String>,
}

impl ImageTarget {
    /// The bands the outputs are written from.
    fn bands(&self) -> crate::maps::Bands<'_> {
        self.painter.bands(&self.outputs, self.size)
    }

    /// The image's `rows` rows from row `row`.
    fn render_rows(&self, row: usize, rows: usize) -> Vec<f32> {
        let [top, left] = self.origin;
        self.painter
            .render([top + row as i64, left], [rows, self.size[1]])
    }
}

/// What paints an image: a trained model's painter (whose samples are endless), or a fitted
/// tile's (periodic, its values clamped to the exemplar's range).
#[allow(clippy::large_enum_variant)] // one per synthesis: boxing would save nothing
pub(super) enum ImagePainter {
    Model(Painter),
    Tile(TilePainter),
}

impl ImagePainter {
    fn channels(&self) -> usize {
        match self {
            ImagePainter::Model(p) => p.channels(),
            ImagePainter::Tile(p) => p.net.shape.channels,
        }
    }

    /// `size` pixels (rows, columns) from `origin`, row-major.
    fn render(&self, origin: [i64; 2], size: [usize; 2]) -> Vec<f32> {
        match self {
            ImagePainter::Model(p) => p.render(&origin, &size),
            ImagePainter::Tile(p) => p.render(origin, size),
        }
    }

    /// The bands `outputs` are written from, `size` pixels from `origin`.
    fn bands<'a>(&self, outputs: &'a [MapOutput], size: [usize; 2]) -> crate::maps::Bands<'a> {
        crate::maps::Bands {
            outputs,
            channels: self.channels(),
            size,
            band_pixels: DEFAULT_BAND_PIXELS,
            clamp: matches!(self, ImagePainter::Tile(_)),
        }
    }
}

/// One painted array: `shape` is `[H, W, C]` (`[D, H, W, C]` for a volume), row-major; `name`
/// is the map's name for a map set.
#[derive(Debug, Clone)]
pub struct Painted {
    pub name: Option<String>,
    pub shape: Vec<usize>,
    pub values: Vec<f32>,
}

impl SynthPlan {
    /// Lines to say before painting: the model, and for a tile how far its period moved.
    pub fn header(&self) -> Vec<String> {
        let mut lines = vec![format!("model: {}", self.model)];
        match &self.target {
            Target::Image(ImageTarget {
                painter: ImagePainter::Model(painter),
                ..
            })
            | Target::Volume { painter, .. } => {
                lines.extend(painter.tile_adjustment().map(|t| t.describe()));
            }
            Target::Image(ImageTarget {
                painter: ImagePainter::Tile(painter),
                ..
            }) => {
                let [rows, cols] = painter.resolution;
                lines[0] = format!(
                    "model: {} (a periodic tile, {cols}x{rows} per period, level of detail {})",
                    self.model, painter.lod
                );
            }
            Target::Slice { .. } => {}
        }
        lines
    }

    /// Rows painted in all, for a progress bar (images and tiles; 0 for volumes and slices).
    pub fn rows(&self) -> usize {
        match &self.target {
            Target::Image(image) => image.size[0],
            _ => 0,
        }
    }

    /// Pixels painted (voxels for a volume).
    pub fn pixels(&self) -> usize {
        match &self.target {
            Target::Image(image) => image.size[0] * image.size[1],
            Target::Slice { image, .. } => image[0] * image[1],
            Target::Volume { shape, .. } => shape.iter().product(),
        }
    }

    /// Paints into memory: one array per file [`SynthPlan::write`] would write (the mesh
    /// aside), value for value what a `.npy` output holds.
    pub fn render(&self) -> Result<Vec<Painted>> {
        match &self.target {
            Target::Image(image) => collect_bands(image.bands(), &image.names, |row, rows| {
                image.render_rows(row, rows)
            }),
            Target::Slice {
                painter,
                origin,
                shape,
                image,
                ..
            } => Ok(vec![Painted {
                name: None,
                shape: vec![image[0], image[1], painter.channels()],
                values: painter.render(origin, shape),
            }]),
            Target::Volume { painter, shape, .. } => Ok(vec![Painted {
                name: None,
                shape: vec![shape[0], shape[1], shape[2], painter.channels()],
                values: painter.render(&[0, 0, 0], shape),
            }]),
        }
    }

    /// Checks that every output file can be written (its folder exists, its format holds the
    /// size) before any work: the command line calls it before saying what it paints.
    pub fn check_destinations(&self) -> Result<()> {
        if let Some((path, _)) = &self.preview {
            crate::io::check_destination(path)?;
        }
        match &self.target {
            Target::Image(image) => {
                crate::maps::check_outputs(&image.outputs, image.size[1], image.size[0])
            }
            Target::Slice { .. } => crate::io::check_destination(&self.out).map(drop),
            Target::Volume { mesh, .. } => {
                crate::io::check_destination(&self.out)?;
                mesh.iter()
                    .try_for_each(|m| crate::io::check_destination(m).map(drop))
            }
        }
    }

    /// Paints into the output files (temporary files renamed when complete), calling
    /// `progress(rows_done)` after each band of an image. Returns the line saying what was
    /// written (the time is the caller's to add).
    pub fn write(&self, progress: impl FnMut(usize)) -> Result<String> {
        let written = self.write_outputs(progress)?;
        match &self.preview {
            Some((path, set)) => {
                let size = self.write_preview(path, set)?;
                Ok(format!(
                    "{written}; preview {} ({}x{})",
                    path.display(),
                    size[1],
                    size[0]
                ))
            }
            None => Ok(written),
        }
    }

    /// Paints the top-left of the image (up to [`preview::MAX_PREVIEW_SIDE`] a side) again and
    /// writes its material lit ([`preview`]). Returns its size.
    fn write_preview(&self, path: &Path, set: &MapSet) -> Result<[usize; 2]> {
        let (values, region) = match &self.target {
            Target::Image(image) => {
                let region = preview::region(image.size);
                (image.painter.render(image.origin, region), region)
            }
            _ => unreachable!("the request gives a preview to images and tiles only"),
        };
        preview::write(path, set, &values, region)?;
        Ok(region)
    }

    fn write_outputs(&self, progress: impl FnMut(usize)) -> Result<String> {
        self.check_destinations()?;
        let out = self.out.display();
        match &self.target {
            Target::Image(image) => {
                let rows = |row, rows| image.render_rows(row, rows);
                image.bands().write(rows, progress)?;
                // A tile is the same for every seed.
                let seed = match image.painter {
                    ImagePainter::Model(_) => format!(", seed {}", self.seed),
                    ImagePainter::Tile(_) => String::new(),
                };
                let [height, width] = image.size;
                Ok(format!(
                    "wrote {} ({width}x{height}{seed}, {:?})",
                    paths(&image.outputs),
                    self.device
                ))
            }
            Target::Slice {
                painter,
                origin,
                shape,
                image,
                format,
                what,
            } => {
                let values = painter.render(origin, shape);
                let mut writer = crate::io::ImageWriter::create(
                    &self.out,
                    *format,
                    image[1],
                    image[0],
                    painter.channels(),
                )?;
                writer.write_rows(&values)?;
                writer.finish()?;
                Ok(format!(
                    "wrote {out} ({what}: {}x{}, seed {})",
                    image[1], image[0], self.seed
                ))
            }
            Target::Volume {
                painter,
                shape,
                format,
                mesh,
            } => self.write_volume(painter, *shape, *format, mesh.as_deref()),
        }
    }

    fn write_volume(
        &self,
        painter: &Painter,
        shape: [usize; 3],
        format: VolumeFormat,
        mesh: Option<&Path>,
    ) -> Result<String> {
        let [depth, height, width] = shape;
        let mut builder = mesh.map(|_| crate::mesh::MeshBuilder::new(height, width));
        painter.write_volume(&self.out, shape, DEFAULT_BAND_PIXELS, builder.as_mut())?;
        let mut said = String::new();
        if let (Some(path), Some(builder)) = (mesh, builder) {
            let mesh = builder.finish();
            crate::mesh::write_mesh(&mesh, path)?;
            said = format!(
                "wrote {}: {} vertices, {} triangles\n",
                path.display(),
                mesh.positions.len(),
                mesh.triangles.len()
            );
        }
        let c = painter.channels();
        let layout = match format {
            VolumeFormat::Npy => String::new(),
            VolumeFormat::Raw => format!(
                ", little-endian float32 [D, H, W, C] = [{depth}, {height}, {width}, {c}], no header"
            ),
        };
        Ok(format!(
            "{said}wrote {} ({width}x{height}x{depth} voxels, {c} channels, seed {}{layout})",
            self.out.display(),
            self.seed
        ))
    }
}

fn paths(outputs: &[MapOutput]) -> String {
    let written: Vec<String> = outputs
        .iter()
        .map(|o| o.path.display().to_string())
        .collect();
    written.join(", ")
}

/// The bands of [`crate::maps::Bands`] gathered into one array per output.
fn collect_bands(
    bands: crate::maps::Bands,
    names: &[String],
    render: impl Fn(usize, usize) -> Vec<f32>,
) -> Result<Vec<Painted>> {
    let [height, width] = bands.size;
    let outputs = bands.outputs;
    let mut painted: Vec<Painted> = outputs
        .iter()
        .enumerate()
        .map(|(i, o)| Painted {
            name: names.get(i).cloned(),
            shape: vec![height, width, o.channels.len()],
            values: Vec::with_capacity(height * width * o.channels.len()),
        })
        .collect();
    bands.for_each(
        render,
        |i, values| {
            painted[i].values.extend(values);
            Ok(())
        },
        |_| {},
    )?;
    Ok(painted)
}
