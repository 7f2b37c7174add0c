//! NumPy volumes as geometry (issue 37): a density from a `.npy` file is the same grid as the
//! same values read from an OpenVDB file — the same majorant grid and trilinear lookup — so a run
//! writes the same bytes; a velocity volume from `.npy` moves the medium as the field it holds.

use std::path::Path;

use glam::DVec3;
use ohd::io::formats::vdb_write::{DenseFloatGrid, to_bytes};
use ohd::run::{Loaded, RunRequest, Unobserved, run};

/// `.npy` bytes of float32 `values` stored x fastest (Fortran order of shape `dims`), as
/// `np.asfortranarray(a, dtype=np.float32)` writes them.
fn npy_fortran(dims: &[usize], values: &[f32]) -> Vec<u8> {
    let shape = dims.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ");
    let header = format!("{{'descr': '<f4', 'fortran_order': True, 'shape': ({shape}), }}\n");
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((header.len() as u16).to_le_bytes());
    b.extend(header.as_bytes());
    b.extend(values.iter().flat_map(|v| v.to_le_bytes()));
    b
}

/// Run `configs/../tests/configs/good/moving_media.toml` with `sets` into `dir`, with the
/// configuration's directory `base` holding the volumes; returns the run's `.npy` files.
fn run_with(base: &Path, dir: &Path, sets: &[String]) -> Vec<(String, Vec<u8>)> {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/configs/good/moving_media.toml"))
            .unwrap();
    let config = base.join("moving_media.toml");
    std::fs::write(&config, text).unwrap();
    let mut sets = sets.to_vec();
    sets.extend(["run.samples=40000".into(), "run.seed=7".into()]);
    let loaded = Loaded::read(Some(&config), &sets).expect("config loads");
    let req = RunRequest { dir: dir.to_path_buf(), no_figures: true, ..Default::default() };
    run(&loaded, &req, &Unobserved).expect("run written");
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "npy"))
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect();
    files.sort();
    files
}

#[test]
fn a_npy_density_runs_as_the_same_grid_from_openvdb() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // A 16 × 16 × 8 density over the belt layer's top (whole 8-voxel leaves from index 0, so the
    // VDB reader's stored block is the array itself).
    let dims = [16usize, 16, 8];
    let n = dims.iter().product::<usize>();
    let values: Vec<f32> = (0..n).map(|i| 0.5 + ((i * 7919) % 1000) as f32 / 1000.0).collect();
    let (voxel, origin) = (2.5e-5, DVec3::new(-1.9e-4, -2.1e-4, 1.25e-5));
    let grid =
        DenseFloatGrid { name: "density", units: "", dims, values: &values, voxel_size: DVec3::splat(voxel), origin };
    std::fs::write(t.join("d.vdb"), to_bytes(&[grid], "ohd test")).unwrap();
    std::fs::write(t.join("d.npy"), npy_fortran(&dims, &values)).unwrap();
    let read = ohd::io::formats::vdb::read_float(t.join("d.vdb"), Some("density")).unwrap();
    assert_eq!((read.grid.min, read.grid.dims), ([0, 0, 0], dims), "the VDB's stored block is the array");

    let vdb = run_with(
        t,
        &t.join("vdb"),
        &["media.belt.density={ type = \"vdb\", file = \"d.vdb\", grid = \"density\" }".into()],
    );
    let npy_set = format!(
        "media.belt.density={{ type = \"npy\", file = \"d.npy\", voxel_size_m = {voxel:?}, translate_m = [{:?}, {:?}, {:?}] }}",
        origin.x, origin.y, origin.z
    );
    let npy = run_with(t, &t.join("npy"), &[npy_set]);
    assert!(vdb.len() >= 4, "{} files", vdb.len());
    for ((name, a), (name_b, b)) in vdb.iter().zip(&npy) {
        assert_eq!(name, name_b);
        assert!(a == b, "{name} differs between the VDB and the .npy density");
    }
    // And the density acts: without it the belt scatters otherwise.
    let plain = run_with(t, &t.join("plain"), &[]);
    assert!(plain.iter().zip(&npy).any(|(a, b)| a.1 != b.1), "the density changed nothing");
    // ohd check names the volume and its source.
    let loaded = Loaded::read(
        Some(&t.join("moving_media.toml")),
        &["media.belt.density={ type = \"npy\", file = \"d.npy\", voxel_size_um = 25 }".to_string()],
    )
    .unwrap();
    let described = loaded.exp.to_string();
    assert!(described.contains("npy") && described.contains("d.npy"), "{described}");
}

#[test]
fn a_npy_velocity_volume_moves_the_medium_as_its_field() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // The belt's uniform velocity (1, 0, 0.5) mm/s in a 2 × 2 × 2 volume of 1 m voxels around the
    // scene, read nearest: the same velocity wherever a path goes, so the same bytes.
    let (dims, v) = ([2usize, 2, 2, 3], [1e-3_f32, 0.0, 5e-4]);
    let values: Vec<f32> = (0..3).flat_map(|c| std::iter::repeat_n(v[c], 8)).collect();
    std::fs::write(t.join("v.npy"), npy_fortran(&dims, &values)).unwrap();
    let uniform = run_with(t, &t.join("uniform"), &[]);
    let set = "media.belt.velocity={ type = \"npy\", file = \"v.npy\", voxel_size_m = 1, translate_m = [-0.5, -0.5, -0.5], interpolation = \"nearest\" }";
    let npy = run_with(t, &t.join("npy"), &[set.into()]);
    assert_eq!(uniform, npy);
    // A wrong shape is refused naming the key and the shape expected.
    std::fs::write(t.join("bad.npy"), npy_fortran(&[2, 2, 2], &values[..8])).unwrap();
    let bad = "media.belt.velocity={ type = \"npy\", file = \"bad.npy\", voxel_size_m = 1 }".to_string();
    let config = t.join("moving_media.toml");
    let e = Loaded::read(Some(&config), &[bad]).unwrap_err().to_string();
    assert!(e.contains("media.belt.velocity.file") && e.contains("(nx, ny, nz, 3)"), "{e}");
    let no_size = "media.belt.velocity={ type = \"npy\", file = \"v.npy\" }".to_string();
    let e = Loaded::read(Some(&config), &[no_size]).unwrap_err().to_string();
    assert!(e.contains("voxel_size"), "{e}");
}
