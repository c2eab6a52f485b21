//! The generator evaluated on a GPU as one CubeCL kernel (wgpu and CUDA).
//!
//! Through burn the generator is about 90 kernels per chunk of points (the encoding, the latent
//! blend, then a matmul, a bias and a ReLU per layer), each writing its activations to device
//! memory and each a launch. This kernel does all of it for a tile of [`TILE`] points per cube:
//! the tile's periodic encoding, latent blend and guidance go into shared memory, every layer
//! runs on that tile in place, and only the tanh outputs are written to device memory. Each of
//! the cube's 128 units holds a register tile of 4 points x `padded / 16` channels (channel
//! `g, g + 16, g + 32, ...` for unit `g` of its row), so a layer is a register-tiled product
//! whose weights are read from the device's caches.
//!
//! It computes what [`super::fused::FusedGenerator`] computes on the CPU, in the same order per
//! point (encoding, then the corner blend of eq. 4 over a [`LatticeBox`]); values differ by the
//! device's rounding of `sin`, `cos`, `exp`, `sqrt`, `tanh` and the order of the sums.
//! Every point is independent, so the result does not depend on how a region is split into
//! launches.

use cubecl::MemoryScope;
use cubecl::prelude::*;
use cubecl::server::Handle;

use super::GeneratorWeights;
use crate::latent::{LatentField, LatticeBox, grid_lattice_bounds};

/// Points per cube.
const TILE: usize = 32;
/// Points per unit.
const POINTS_PER_UNIT: usize = 4;
/// Units across the channels of a layer.
const CHANNEL_GROUPS: usize = 16;
/// Units per cube: `TILE / POINTS_PER_UNIT` rows of `CHANNEL_GROUPS`.
const UNITS: usize = TILE / POINTS_PER_UNIT * CHANNEL_GROUPS;
/// Points per launch: bounds the output buffer (4 Mi floats for 4 channels) while keeping
/// launches few.
pub const LAUNCH_POINTS: usize = 1 << 20;

/// Evaluates the generator at points `start..start + n` (row-major) of a box of coordinates.
///
/// - `reals`: `[K (dims), latent_scale (dims), sigma, axis coordinates...]`
/// - `ints`: `[lattice lows (dims), lattice strides (dims), box sizes (dims), box strides
///   (dims), axis offsets into reals (dims), layer offsets into weights (layers), layer inputs
///   (layers)]`
/// - `table`: `[cells, latent_dim]` lattice vectors of the box
/// - `weights`: per layer, `W` as `[inputs, padded]` then the bias as `[padded]`, zero-padded
/// - `guide`: `[n]` guidance values of a guided model (unread otherwise)
/// - `out`: `[n, channels]`
#[allow(clippy::too_many_arguments, clippy::approx_constant)]
#[cube(launch)]
fn generator_kernel(
    reals: &[f32],
    ints: &[i32],
    table: &[f32],
    weights: &[f32],
    guide: &[f32],
    out: &mut [f32],
    start: u32,
    n: u32,
    latent_dim: u32,
    #[comptime] dims: usize,
    #[comptime] octaves: usize,
    #[comptime] padded: usize,
    #[comptime] layers: usize,
    #[comptime] channels: usize,
    #[comptime] guided: bool,
) {
    let unit = UNIT_POS as usize;
    let first = CUBE_POS * TILE;
    let n = n as usize;
    let ld = latent_dim as usize;
    let enc = 2 * octaves * dims;
    let mut act = Shared::<[f32]>::new_slice(TILE * padded);

    // Input rows: [encoding(p / K), latent(p * latent_scale), guidance]  -> act[TILE, padded]
    if unit < TILE {
        let row = unit * padded;
        let i = first + unit;
        for k in 0..padded {
            act[row + k] = 0.0f32;
        }
        if i < n {
            let g = start as usize + i;
            let mut frac = Array::<f32>::new(3usize);
            let mut cell = 0usize;
            #[unroll]
            for d in 0..dims {
                let index = (g / ints[3 * dims + d] as usize) % ints[2 * dims + d] as usize;
                let p = reals[ints[4 * dims + d] as usize + index];
                let q = p / reals[d];
                // π as a literal: a path to `f32::consts::PI` does not compile into a kernel.
                let mut frequency = 3.1415927f32;
                #[unroll]
                for j in 0..octaves {
                    let angle = frequency * q;
                    act[row + d * 2 * octaves + j] = angle.sin();
                    act[row + d * 2 * octaves + octaves + j] = angle.cos();
                    frequency *= 2.0f32;
                }
                let u = p * reals[dims + d];
                let floor = u.floor();
                frac[d] = u - floor;
                cell += (floor as i32 - ints[d]) as usize * ints[dims + d] as usize;
            }
            // The corner blend of eq. 4: softmax over corners of -distance / sigma.
            let sigma = reals[2 * dims];
            let mut weight = Array::<f32>::new(8usize);
            #[unroll]
            for corner in 0..(1usize << dims) {
                let mut dist2 = 0.0f32;
                #[unroll]
                for d in 0..dims {
                    let t = select((corner >> d) & 1 == 1, 1.0f32 - frac[d], frac[d]);
                    dist2 += t * t;
                }
                weight[corner] = -dist2.sqrt() / sigma;
            }
            let mut top = weight[0];
            #[unroll]
            for corner in 1..(1usize << dims) {
                top = max(top, weight[corner]);
            }
            let mut total = 0.0f32;
            #[unroll]
            for corner in 0..(1usize << dims) {
                let e = (weight[corner] - top).exp();
                weight[corner] = e;
                total += e;
            }
            #[unroll]
            for corner in 0..(1usize << dims) {
                let mut shift = 0usize;
                #[unroll]
                for d in 0..dims {
                    shift += ((corner >> d) & 1) * ints[dims + d] as usize;
                }
                let w = weight[corner] / total;
                let at = (cell + shift) * ld;
                for c in 0..ld {
                    act[row + enc + c] += w * table[at + c];
                }
            }
            if guided {
                act[row + enc + ld] = guide[i];
            }
        }
    }
    sync_cube();

    // Layers, in place on the tile: this unit's points pg*4.. and channels cg + 16j.
    let per = padded / CHANNEL_GROUPS;
    let pg = unit / CHANNEL_GROUPS;
    let cg = unit % CHANNEL_GROUPS;
    let mut acc = Array::<f32>::new(POINTS_PER_UNIT * per);
    let mut a = Array::<f32>::new(POINTS_PER_UNIT);
    let mut w = Array::<f32>::new(per);
    for l in 0..layers {
        let w0 = ints[5 * dims + l] as usize;
        let inputs = ints[5 * dims + layers + l] as usize;
        #[unroll]
        for e in 0..POINTS_PER_UNIT * per {
            acc[e] = 0.0f32;
        }
        for k in 0..inputs {
            #[unroll]
            for i in 0..POINTS_PER_UNIT {
                a[i] = act[(pg * POINTS_PER_UNIT + i) * padded + k];
            }
            #[unroll]
            for j in 0..per {
                w[j] = weights[w0 + k * padded + cg + j * CHANNEL_GROUPS];
            }
            #[unroll]
            for i in 0..POINTS_PER_UNIT {
                #[unroll]
                for j in 0..per {
                    acc[i * per + j] += a[i] * w[j];
                }
            }
        }
        let b0 = w0 + inputs * padded;
        sync_cube();
        if l + 1 < layers {
            #[unroll]
            for i in 0..POINTS_PER_UNIT {
                #[unroll]
                for j in 0..per {
                    let c = cg + j * CHANNEL_GROUPS;
                    act[(pg * POINTS_PER_UNIT + i) * padded + c] =
                        max(acc[i * per + j] + weights[b0 + c], 0.0f32);
                }
            }
        } else {
            #[unroll]
            for i in 0..POINTS_PER_UNIT {
                let point = first + pg * POINTS_PER_UNIT + i;
                #[unroll]
                for j in 0..per {
                    let c = cg + j * CHANNEL_GROUPS;
                    if point < n && c < channels {
                        // tanh saturates to ±1 in f32 beyond ±15; clamping keeps drivers that
                        // compute it from exp away from inf / inf.
                        let v = min(max(acc[i * per + j] + weights[b0 + c], -15.0f32), 15.0f32);
                        out[point * channels + c] = v.tanh();
                    }
                }
            }
        }
        sync_cube();
    }
}

/// A generator held on a GPU as padded weights for [`generator_kernel`].
pub struct KernelGenerator {
    client: Client,
    weights: Handle,
    weights_len: usize,
    k: Vec<f32>,
    dims: usize,
    octaves: usize,
    padded: usize,
    layer_offsets: Vec<i32>,
    layer_inputs: Vec<i32>,
    channels: usize,
    input_width: usize,
    launch_points: usize,
}

impl std::fmt::Debug for KernelGenerator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KernelGenerator")
            .field("dims", &self.dims)
            .field("padded", &self.padded)
            .field("layers", &self.layer_inputs.len())
            .finish()
    }
}

impl KernelGenerator {
    /// Uploads `weights` to `device`'s CubeCL client, or `None` when the kernel does not apply:
    /// a device burn does not run on CubeCL (flex), or a model whose widest layer does not fit
    /// a tile in the device's shared memory.
    pub fn new(weights: &GeneratorWeights, device: &burn::tensor::Device) -> Option<Self> {
        let client = cube_client(device)?;
        let dims = weights.k.len();
        let widest = weights
            .layers
            .iter()
            .map(|l| l.inputs.max(l.outputs))
            .max()?;
        let padded = widest.div_ceil(CHANNEL_GROUPS) * CHANNEL_GROUPS;
        let shared = TILE * padded * size_of::<f32>();
        let hardware = &client.properties().hardware;
        if shared > hardware.max_shared_memory_size
            || UNITS as u32 > hardware.max_units_per_cube
            || padded / CHANNEL_GROUPS > 16
        {
            return None;
        }
        let mut packed = Vec::new();
        let (mut layer_offsets, mut layer_inputs) = (Vec::new(), Vec::new());
        for layer in &weights.layers {
            layer_offsets.push(i32::try_from(packed.len()).ok()?);
            layer_inputs.push(layer.inputs as i32);
            for row in layer.weight.chunks_exact(layer.outputs) {
                packed.extend_from_slice(row);
                packed.resize(packed.len() + padded - layer.outputs, 0.0);
            }
            packed.extend_from_slice(&layer.bias);
            packed.resize(packed.len() + padded - layer.outputs, 0.0);
        }
        let last = weights.layers.last()?;
        Some(Self {
            weights: client.create_from_slice(f32::as_bytes(&packed)),
            weights_len: packed.len(),
            client,
            k: weights.k.clone(),
            dims,
            octaves: weights.octaves,
            padded,
            layer_offsets,
            layer_inputs,
            channels: last.outputs,
            input_width: weights.layers[0].inputs,
            launch_points: LAUNCH_POINTS,
        })
    }

    /// Points per launch (default [`LAUNCH_POINTS`]); the output does not depend on it.
    pub fn with_launch_points(mut self, points: usize) -> Self {
        self.launch_points = points.max(1);
        self
    }

    /// Evaluates the generator on the grid `axes[0] x axes[1] (x axes[2])` (coordinates per
    /// axis, row-major, last axis fastest), looking the latent field up at `p * latent_scale`.
    /// `guide(start, count)` gives the guidance values of points `start..start + count`, empty
    /// for an unguided model.
    ///
    /// # Shapes
    /// - output: `[points, channels]`, row-major over the axes
    pub fn render(
        &self,
        field: &LatentField,
        latent_scale: &[f32],
        axes: &[Vec<f32>],
        mut guide: impl FnMut(usize, usize) -> Vec<f32>,
    ) -> Vec<f32> {
        let dims = self.dims;
        assert_eq!(axes.len(), dims, "one coordinate list per axis");
        let total: usize = axes.iter().map(Vec::len).product();
        let mut out = Vec::with_capacity(total * self.channels);
        if total == 0 {
            return out;
        }
        assert!(
            total <= i32::MAX as usize,
            "a box of at most 2^31 points per render"
        );
        let (lo, hi) = grid_lattice_bounds(axes, latent_scale);
        let lattice = LatticeBox::new(&[(field, lo, hi)]);
        let ld = field.latent_dim();
        let guided = self.input_width > self.octaves * 2 * dims + ld;

        let mut reals = self.k.clone();
        reals.extend_from_slice(latent_scale);
        reals.push(field.sigma());
        let mut axis_offsets = Vec::with_capacity(dims);
        for a in axes {
            axis_offsets.push(reals.len() as i32);
            reals.extend_from_slice(a);
        }
        let sizes: Vec<i32> = axes.iter().map(|a| a.len() as i32).collect();
        let mut box_strides = vec![1i32; dims];
        for d in (0..dims - 1).rev() {
            box_strides[d] = box_strides[d + 1] * sizes[d + 1];
        }
        let mut ints: Vec<i32> = lattice.lows.iter().map(|&v| v as i32).collect();
        ints.extend(lattice.strides.iter().map(|&v| v as i32));
        ints.extend_from_slice(&sizes);
        ints.extend_from_slice(&box_strides);
        ints.extend_from_slice(&axis_offsets);
        ints.extend_from_slice(&self.layer_offsets);
        ints.extend_from_slice(&self.layer_inputs);

        let client = &self.client;
        let reals = (client.create_from_slice(f32::as_bytes(&reals)), reals.len());
        let ints = (client.create_from_slice(i32::as_bytes(&ints)), ints.len());
        let table = (
            client.create_from_slice(f32::as_bytes(&lattice.values)),
            lattice.values.len(),
        );
        let max_cubes = client.properties().hardware.max_cube_count.0.max(1) as usize;

        // Launch chunk i + 1 before reading chunk i back, so the device never waits on the host.
        let mut pending: Option<(Handle, usize)> = None;
        let read = |pending: Option<(Handle, usize)>, out: &mut Vec<f32>| {
            if let Some((handle, len)) = pending {
                let bytes = client
                    .read_one(handle)
                    .expect("the generator kernel's output is readable");
                out.extend_from_slice(&f32::from_bytes(&bytes)[..len]);
            }
        };
        for start in (0..total).step_by(self.launch_points) {
            let n = self.launch_points.min(total - start);
            let g = guide(start, n);
            let g = if guided {
                assert_eq!(g.len(), n, "a guided model needs a value per point");
                g
            } else {
                vec![0.0]
            };
            let guide_handle = client.create_from_slice(f32::as_bytes(&g));
            let len = n * self.channels;
            let output = client.empty(len * size_of::<f32>());
            let cubes = n.div_ceil(TILE);
            let x = cubes.min(max_cubes);
            let y = cubes.div_ceil(x);
            // SAFETY: each handle holds at least the number of f32 elements stated.
            unsafe {
                generator_kernel::launch(
                    client,
                    CubeCount::Static(x as u32, y as u32, 1),
                    CubeDim::new_1d(UNITS as u32),
                    BufferArg::from_raw_parts(reals.0.clone(), reals.1),
                    BufferArg::from_raw_parts(ints.0.clone(), ints.1),
                    BufferArg::from_raw_parts(table.0.clone(), table.1),
                    BufferArg::from_raw_parts(self.weights.clone(), self.weights_len),
                    BufferArg::from_raw_parts(guide_handle, g.len()),
                    BufferArg::from_raw_parts(output.clone(), len),
                    start as u32,
                    n as u32,
                    ld as u32,
                    dims,
                    self.octaves,
                    self.padded,
                    self.layer_inputs.len(),
                    self.channels,
                    guided,
                );
            }
            read(pending.replace((output, len)), &mut out);
        }
        read(pending.take(), &mut out);
        out
    }

    /// The largest single buffer this process has allocated on the kernel's device so far, in
    /// bytes (every memory pool of every stream, burn's included). The kernel's own buffers are
    /// its weights, a region's lattice vectors and coordinates, and one launch's guidance and
    /// output, so for a render this is bounded by the launch, not by the size of the region.
    pub fn largest_device_allocation(&self) -> u64 {
        self.client
            .memory_report(MemoryScope::Device)
            .streams
            .iter()
            .flat_map(|stream| {
                let pools = &stream.pools;
                pools
                    .dynamic
                    .iter()
                    .chain([&pools.persistent, &pools.dedicated])
            })
            .map(|pool| pool.largest_alloc)
            .max()
            .unwrap_or(0)
    }
}

/// The CubeCL client behind a burn device, if burn runs it on CubeCL (wgpu, CUDA). burn
/// registers its servers in CubeCL's process-wide table, so this is burn's own client.
fn cube_client(device: &burn::tensor::Device) -> Option<Client> {
    let device = device.clone().inner();
    #[allow(unreachable_patterns)]
    match device.as_dispatch() {
        burn_dispatch::DispatchDevice::Cube(device) => Some(device.client()),
        _ => None,
    }
}
