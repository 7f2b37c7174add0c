//! The OpenVDB reader against files written by OpenVDB 10 itself (`tests/fixtures/vdb/`, made by
//! `validation/vdb/make_fixtures.sh`): every active voxel and every sample point bit-exactly
//! against what OpenVDB returns, in every codec, plus the error cases.

use std::io::Read;
use std::path::{Path, PathBuf};

use glam::DVec3;
use ohd::error::Error;
use ohd::io::formats::vdb::{self, ReadOptions, ValueType, VdbGrid, VdbTree, VdbValue};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/vdb").join(name)
}

/// One grid's truth as dumped by pyopenvdb (see validation/vdb/scene.py).
#[derive(Debug, Default, Clone)]
struct Truth {
    name: String,
    value_type: String,
    class: String,
    half: bool,
    background: Vec<u32>,
    map: String,
    world0: [f64; 3],
    world1: [f64; 3],
    active_count: u64,
    active_bbox: ([i32; 3], [i32; 3]),
    /// Active values: voxels (min == max) and tiles, with their value bits.
    on: Vec<([i32; 3], [i32; 3], Vec<u32>)>,
    /// Sample points: index, isValueOn, getValue bits.
    samples: Vec<([i32; 3], bool, Vec<u32>)>,
}

fn read_truth(name: &str) -> Vec<Truth> {
    let mut text = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(fixture(name)).expect("truth file"))
        .read_to_string(&mut text)
        .expect("gzip text");
    let mut out = Vec::new();
    let mut t = Truth::default();
    let ints = |w: &[&str]| -> Vec<i32> { w.iter().map(|s| s.parse().expect("int")).collect() };
    let hexes = |w: &[&str]| -> Vec<u32> { w.iter().map(|s| u32::from_str_radix(s, 16).expect("hex")).collect() };
    let coord = |v: &[i32]| [v[0], v[1], v[2]];
    for line in text.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w[0] {
            "grid" => t = Truth { name: w[1].to_string(), ..Truth::default() },
            "type" => t.value_type = w[1].to_string(),
            "class" => t.class = w[1..].join(" "),
            "half" => t.half = w[1] == "1",
            "background" => t.background = hexes(&w[1..]),
            "map" => t.map = w[1].to_string(),
            "world0" => t.world0 = std::array::from_fn(|a| w[1 + a].parse().expect("f64")),
            "world1" => t.world1 = std::array::from_fn(|a| w[1 + a].parse().expect("f64")),
            "active_count" => t.active_count = w[1].parse().expect("count"),
            "active_bbox" => {
                let v = ints(&w[1..7]);
                t.active_bbox = (coord(&v[0..3]), coord(&v[3..6]));
            }
            "on" => {
                let v = ints(&w[1..7]);
                t.on.push((coord(&v[0..3]), coord(&v[3..6]), hexes(&w[7..])));
            }
            "s" => {
                let v = ints(&w[1..4]);
                t.samples.push((coord(&v), w[4] == "1", hexes(&w[5..])));
            }
            "end" => out.push(t.clone()),
            other => panic!("unknown truth line {other}"),
        }
    }
    out
}

trait Bits: VdbValue {
    fn bits(self) -> Vec<u32>;
}
impl Bits for f32 {
    fn bits(self) -> Vec<u32> {
        vec![self.to_bits()]
    }
}
impl Bits for [f32; 3] {
    fn bits(self) -> Vec<u32> {
        self.iter().map(|v| v.to_bits()).collect()
    }
}

fn check_header<T: Bits>(file: &str, tree: &VdbTree<T>, t: &Truth) {
    let info = &tree.info;
    assert_eq!(info.name, t.name, "{file}");
    let vt = if t.value_type == "float" { ValueType::Float } else { ValueType::Vec3s };
    assert_eq!(info.value_type, vt, "{file} {}", t.name);
    assert_eq!(info.class, t.class, "{file} {}", t.name);
    assert_eq!(info.half, t.half, "{file} {}", t.name);
    assert_eq!(info.map_type, t.map, "{file} {}", t.name);
    assert_eq!(tree.background.bits(), t.background, "{file} {} background", t.name);
    let w0 = tree.transform.to_world(DVec3::ZERO);
    let w1 = tree.transform.to_world(DVec3::ONE);
    assert_eq!(w0.to_array(), t.world0, "{file} {} index (0,0,0) in the world", t.name);
    assert_eq!(w1.to_array(), t.world1, "{file} {} index (1,1,1) in the world", t.name);
    let (count, bbox) = tree.active_stats();
    assert_eq!(count, t.active_count, "{file} {} active voxel count", t.name);
    assert_eq!(bbox, Some(t.active_bbox), "{file} {} active bbox", t.name);
}

/// Sparse access at every sample point and at every active voxel (tiles: corners and centre).
fn check_tree<T: Bits>(file: &str, tree: &VdbTree<T>, t: &Truth) -> usize {
    check_header(file, tree, t);
    let mut checked = 0;
    for (p, on, bits) in &t.samples {
        let (v, a) = tree.probe(*p);
        assert_eq!((v.bits(), a), (bits.clone(), *on), "{file} {} sample {p:?}", t.name);
        checked += 1;
    }
    for (lo, hi, bits) in &t.on {
        let mid = std::array::from_fn(|a| ((i64::from(lo[a]) + i64::from(hi[a])) / 2) as i32);
        for p in [*lo, *hi, mid] {
            let (v, a) = tree.probe(p);
            assert!(a && v.bits() == *bits, "{file} {} active value at {p:?}", t.name);
        }
    }
    checked
}

/// The dense block: every active voxel (tiles expanded), every sample point.
fn check_dense<T: Bits>(file: &str, g: &VdbGrid<T>, t: &Truth) -> u64 {
    let mut n = 0u64;
    for (lo, hi, bits) in &t.on {
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    let p = [i, j, k];
                    if !g.active.contains(p) || g.grid.get(p).bits() != *bits {
                        panic!(
                            "{file} {}: active voxel {p:?} reads {:?}, active {}",
                            t.name,
                            g.grid.get(p),
                            g.active.contains(p)
                        );
                    }
                    n += 1;
                }
            }
        }
    }
    assert_eq!(n, t.active_count, "{file} {}", t.name);
    assert_eq!(g.active.count(), t.active_count, "{file} {} active mask", t.name);
    assert_eq!(g.active_voxel_count, t.active_count, "{file} {}", t.name);
    assert_eq!(g.active_bbox, Some(t.active_bbox), "{file} {}", t.name);
    for (p, on, bits) in &t.samples {
        assert_eq!(g.grid.get(*p).bits(), *bits, "{file} {} dense value at {p:?}", t.name);
        assert_eq!(g.active.contains(*p), *on, "{file} {} dense active state at {p:?}", t.name);
    }
    // Active voxels iterate in the block's order and are all active.
    let first: Vec<[i32; 3]> = g.active.iter().take(1000).collect();
    assert!(first.iter().all(|p| g.active.contains(*p)));
    n
}

fn check_file(file: &str, truth: &[Truth], dense: bool) -> (usize, u64) {
    let path = fixture(file);
    let mut infos = vdb::grids(&path).expect("grids()");
    infos.sort_by(|a, b| a.name.cmp(&b.name));
    let mut truth = truth.to_vec();
    truth.sort_by(|a, b| a.name.cmp(&b.name));
    assert_eq!(
        infos.iter().map(|i| i.name.clone()).collect::<Vec<_>>(),
        truth.iter().map(|t| t.name.clone()).collect::<Vec<_>>()
    );
    let opts = ReadOptions::default();
    let (mut samples, mut voxels) = (0, 0);
    for (info, t) in infos.iter().zip(&truth) {
        assert_eq!(info.file_voxel_count, Some(t.active_count), "{file} {}", t.name);
        if t.value_type == "float" {
            let tree = vdb::read_tree::<f32>(&path, Some(&t.name), &opts).expect("read_tree");
            samples += check_tree(file, &tree, t);
            if dense {
                voxels += check_dense(file, &vdb::read_float(&path, Some(&t.name)).expect("read_float"), t);
            }
        } else {
            let tree = vdb::read_tree::<[f32; 3]>(&path, Some(&t.name), &opts).expect("read_tree");
            samples += check_tree(file, &tree, t);
            if dense {
                voxels += check_dense(file, &vdb::read_vec3(&path, Some(&t.name)).expect("read_vec3"), t);
            }
        }
    }
    (samples, voxels)
}

const ENCODINGS: [(&str, u32); 6] =
    [("none", 0), ("zip", 1), ("active", 2), ("zip_active", 3), ("blosc", 4), ("blosc_active", 6)];
const HALF_ENCODINGS: [(&str, u32); 4] = [("zip", 1), ("zip_active", 3), ("blosc", 4), ("blosc_active", 6)];

#[test]
fn full_precision_scene_in_every_codec_is_bit_exact() {
    let truth = read_truth("scene.truth.gz");
    assert_eq!(truth.len(), 2);
    for (enc, flags) in ENCODINGS {
        let file = format!("scene_{enc}.vdb");
        let infos = vdb::grids(fixture(&file)).unwrap();
        assert!(infos.iter().all(|i| i.compression == flags && !i.half), "{file}: {infos:?}");
        let (s, v) = check_file(&file, &truth, true);
        assert!(s > 8000 && v == 2 * 2_099_402, "{file}: {s} samples, {v} voxels");
    }
}

#[test]
fn half_float_scene_in_every_codec_is_bit_exact_and_float16_rounded() {
    let truth = read_truth("scene_half.truth.gz");
    for (enc, flags) in HALF_ENCODINGS {
        let file = format!("scene_half_{enc}.vdb");
        let infos = vdb::grids(fixture(&file)).unwrap();
        assert!(
            infos.iter().all(|i| i.compression == flags && i.half && i.tree_type.ends_with("_HalfFloat")),
            "{file}"
        );
        check_file(&file, &truth, true);
    }
    // The half truth is the full truth rounded to float16 (round to nearest even), value by value.
    let full = read_truth("scene.truth.gz");
    let r = |b: u32| half::f16::from_f32(f32::from_bits(b)).to_f32().to_bits();
    for (h, f) in truth.iter().zip(&full) {
        assert_eq!(h.samples.len(), f.samples.len());
        for (a, b) in h.samples.iter().zip(&f.samples) {
            assert_eq!(a.0, b.0);
            assert_eq!(a.2, b.2.iter().map(|&x| r(x)).collect::<Vec<_>>(), "{} at {:?}", h.name, a.0);
        }
        assert_eq!(h.background, f.background.iter().map(|&x| r(x)).collect::<Vec<_>>());
    }
}

#[test]
fn zero_background_vec3_fog_class_and_scale_map() {
    let truth = read_truth("extra.truth.gz");
    let (s, v) = check_file("extra.vdb", &truth, true);
    assert!(s > 1000 && v > 500, "{s} {v}");
    let half = read_truth("extra_half.truth.gz");
    check_file("extra_half.vdb", &half, true);
    let fog = vdb::read_float(fixture("extra.vdb"), Some("fog")).unwrap();
    assert_eq!(fog.info.class, "fog volume");
    assert_eq!(fog.grid.transform.voxel_size, DVec3::new(0.1, 0.2, 0.4));
}

#[test]
fn root_tiles_read_sparse_and_the_dense_block_is_refused_with_its_estimate() {
    let truth = read_truth("root_tile.truth.gz");
    let path = fixture("root_tile.vdb");
    check_file("root_tile.vdb", &truth, false);
    let tree = vdb::read_tree::<f32>(&path, Some("density"), &ReadOptions::default()).unwrap();
    let mut tiles = tree.root_tiles();
    tiles.sort_by_key(|t| t.origin);
    assert_eq!(tiles.len(), 2);
    assert_eq!((tiles[0].origin, tiles[0].value, tiles[0].active), ([-4096; 3], 0.5, true));
    assert_eq!((tiles[1].origin, tiles[1].value, tiles[1].active), ([0, 0, -4096], 0.125, false));
    assert_eq!(tree.stored_bbox(), Some(([-4096; 3], [4095, 4095, 15])));
    let err = vdb::read_float(&path, Some("density")).unwrap_err().to_string();
    assert!(err.contains("root_tile.vdb") && err.contains("\"density\"") && err.contains("memory budget"), "{err}");
    assert!(err.contains("8192×8192×4112"), "{err}");
    let err = vdb::read_vec3(&path, Some("velocity")).unwrap_err().to_string();
    assert!(err.contains("memory budget"), "{err}");
}

#[test]
fn memory_budget_is_a_parameter() {
    let path = fixture("scene_blosc_active.vdb");
    let small = ReadOptions { max_dense_bytes: 1 << 20 };
    let err = vdb::read_grid::<f32>(&path, Some("density"), &small).unwrap_err().to_string();
    assert!(err.contains("248×128×128") && err.contains("1048576"), "{err}");
    let g = vdb::read_grid::<f32>(&path, Some("density"), &ReadOptions { max_dense_bytes: 32 << 20 }).unwrap();
    assert_eq!(g.grid.dims, [248, 128, 128]);
    assert_eq!(g.grid.min, [-256, -128, -128]);
}

#[test]
fn supported_maps_and_clear_errors_for_the_others() {
    let truth = read_truth("transforms.truth.gz");
    let path = fixture("transforms.vdb");
    let opts = ReadOptions::default();
    let mut ok = 0;
    for t in &truth {
        match t.map.as_str() {
            "AffineMap" | "UnitaryMap" | "NonlinearFrustumMap" => {
                let err = vdb::read_float(&path, Some(&t.name)).unwrap_err();
                assert!(matches!(err, Error::Vdb(_)));
                let msg = err.to_string();
                assert!(msg.contains("transforms.vdb") && msg.contains(&t.name) && msg.contains(&t.map), "{msg}");
                // The tree is fine: listing works.
                assert!(vdb::grids(&path).unwrap().iter().any(|i| i.map_type == t.map));
            }
            _ if t.name == "negative_scale" => {
                let msg = vdb::read_float(&path, Some(&t.name)).unwrap_err().to_string();
                assert!(msg.contains("negative_scale") && msg.contains("positive"), "{msg}");
            }
            _ => {
                let tree = vdb::read_tree::<f32>(&path, Some(&t.name), &opts).unwrap();
                check_tree("transforms.vdb", &tree, t);
                check_dense("transforms.vdb", &vdb::read_float(&path, Some(&t.name)).unwrap(), t);
                ok += 1;
            }
        }
    }
    assert_eq!(ok, 5, "scale, translation, uniform scale, uniform scale+translate, scale+translate");
}

#[test]
fn type_mismatch_missing_grid_and_first_grid_of_a_type() {
    let path = fixture("scene_blosc_active.vdb");
    let msg = vdb::read_vec3(&path, Some("density")).unwrap_err().to_string();
    assert!(
        msg.contains("scene_blosc_active.vdb") && msg.contains("Tree_float_5_4_3") && msg.contains("Tree_vec3s_5_4_3"),
        "{msg}"
    );
    let msg = vdb::read_float(&path, Some("velocity")).unwrap_err().to_string();
    assert!(msg.contains("Tree_vec3s_5_4_3"), "{msg}");
    let msg = vdb::read_float(&path, Some("nope")).unwrap_err().to_string();
    assert!(msg.contains("no grid named \"nope\"") && msg.contains("density"), "{msg}");
    assert_eq!(vdb::read_vec3(&path, None).unwrap().info.name, "velocity");
    assert_eq!(vdb::read_float(&path, None).unwrap().info.name, "density");
}

#[test]
fn missing_file_and_files_that_are_not_vdb() {
    let missing = fixture("no_such_file.vdb");
    let err = vdb::grids(&missing).unwrap_err();
    assert!(matches!(err, Error::Read { .. }) && err.to_string().contains("no_such_file.vdb"));
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in [
        ("empty.vdb", Vec::new()),
        ("text.vdb", b"this is not a VDB file at all, just text".to_vec()),
        ("gz.vdb", std::fs::read(fixture("scene.truth.gz")).unwrap()),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let msg = vdb::read_float(&p, None).unwrap_err().to_string();
        assert!(msg.contains(name) && msg.contains("not an OpenVDB file"), "{msg}");
        assert!(vdb::grids(&p).is_err());
    }
    // Unsupported format versions.
    let mut bytes = std::fs::read(fixture("extra.vdb")).unwrap();
    for v in [221u32, 225, 0xffff_ffff] {
        bytes[8..12].copy_from_slice(&v.to_le_bytes());
        let p = dir.path().join("version.vdb");
        std::fs::write(&p, &bytes).unwrap();
        let msg = vdb::grids(&p).unwrap_err().to_string();
        assert!(msg.contains(&format!("version {v}")), "{msg}");
    }
}

fn read_all_sparse(p: &Path) -> bool {
    let opts = ReadOptions::default();
    let Ok(infos) = vdb::grids(p) else { return false };
    let mut ok = true;
    for i in infos {
        ok &= match i.value_type {
            ValueType::Float => vdb::read_tree::<f32>(p, Some(&i.unique_name), &opts).is_ok(),
            ValueType::Vec3s => vdb::read_tree::<[f32; 3]>(p, Some(&i.unique_name), &opts).is_ok(),
            ValueType::Other(_) => false,
        };
    }
    ok
}

#[test]
fn truncated_and_corrupted_files_give_errors_never_panics() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("cut.vdb");
    for file in ["scene_blosc_active.vdb", "scene_half_zip_active.vdb", "scene_zip.vdb", "extra.vdb"] {
        let bytes = std::fs::read(fixture(file)).unwrap();
        let mut cuts: Vec<usize> = (0..200).collect();
        cuts.extend((0..300).map(|i| i * bytes.len() / 300));
        cuts.push(bytes.len() - 1);
        for cut in cuts {
            std::fs::write(&p, &bytes[..cut]).unwrap();
            let r = std::panic::catch_unwind(|| read_all_sparse(&p));
            assert!(matches!(r, Ok(false)), "{file} cut at {cut}: {r:?}");
            let msg = vdb::read_float(&p, None).map(|_| ()).unwrap_err().to_string();
            assert!(msg.contains("cut.vdb"), "{msg}");
        }
        // Flipped bytes: any outcome but a panic (a flipped value byte is still a valid file).
        // OHD_VDB_FUZZ=N runs N flips per file instead of 400.
        let flips: usize = std::env::var("OHD_VDB_FUZZ").ok().and_then(|v| v.parse().ok()).unwrap_or(400);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..flips {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let mut bad = bytes.clone();
            let at = (state % bytes.len() as u64) as usize;
            bad[at] ^= 1 << ((state >> 32) % 8);
            std::fs::write(&p, &bad).unwrap();
            let r = std::panic::catch_unwind(|| read_all_sparse(&p));
            assert!(r.is_ok(), "{file}: panic with byte {at} flipped");
        }
        // Large counts and sizes written into every 8-byte-aligned position of the header and
        // topology: errors, without allocating what they claim.
        for at in (0..bytes.len().min(20_000) - 8).step_by(4) {
            let mut bad = bytes.clone();
            bad[at..at + 4].copy_from_slice(&0x7fff_fff0u32.to_le_bytes());
            std::fs::write(&p, &bad).unwrap();
            let r = std::panic::catch_unwind(|| read_all_sparse(&p));
            assert!(r.is_ok(), "{file}: panic with a large count at {at}");
        }
    }
}

/// Load times of every fixture and of the generated dense files (run with
/// `cargo test --release --test vdb -- --ignored --nocapture`; the dense files come from
/// `BENCH=1 bash validation/vdb/make_fixtures.sh`).
#[test]
#[ignore]
fn load_times() {
    let mut files: Vec<PathBuf> = std::fs::read_dir(fixture(""))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "vdb"))
        .collect();
    files.sort();
    for n in [128, 256] {
        let p = PathBuf::from(format!("/tmp/ohd-vdb-bench/dense_{n}.vdb"));
        if p.exists() {
            files.push(p);
        }
    }
    for p in files {
        let size = std::fs::metadata(&p).unwrap().len();
        for info in vdb::grids(&p).unwrap() {
            let t = std::time::Instant::now();
            let reps = 3;
            let mut what = String::new();
            for _ in 0..reps {
                what = match info.value_type {
                    ValueType::Float => match vdb::read_float(&p, Some(&info.unique_name)) {
                        Ok(g) => format!("dense {:?}", g.grid.dims),
                        Err(_) => "refused".into(),
                    },
                    ValueType::Vec3s => match vdb::read_vec3(&p, Some(&info.unique_name)) {
                        Ok(g) => format!("dense {:?}", g.grid.dims),
                        Err(_) => "refused".into(),
                    },
                    ValueType::Other(_) => "skipped".into(),
                };
            }
            let ms = t.elapsed().as_secs_f64() * 1e3 / reps as f64;
            println!(
                "{:<32} {:>9} B  {:<24} {:>8.2} ms  {}",
                p.file_name().unwrap().to_string_lossy(),
                size,
                info.name,
                ms,
                what
            );
        }
    }
}
