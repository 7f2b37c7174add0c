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

/// A `.npy` header for float32 data of shape `dims` (C order) and no data: the file is then
/// made as long as the header declares with `set_len`, a sparse file that takes no disk.
fn sparse_npy(path: &Path, dims: &[u64]) {
    let shape = dims.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ");
    let header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({shape}), }}\n");
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((header.len() as u16).to_le_bytes());
    b.extend(header.as_bytes());
    let len = b.len() as u64 + 4 * dims.iter().product::<u64>();
    std::fs::write(path, b).unwrap();
    std::fs::File::options().write(true).open(path).unwrap().set_len(len).unwrap();
}

/// `ohd check` of moving_media.toml in `dir` with `prefix` run first by the shell (a limit) and
/// `sets`: exit status and standard error.
fn check_with(dir: &Path, prefix: &str, sets: &[&str]) -> (Option<i32>, String) {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/configs/good/moving_media.toml"))
            .unwrap();
    std::fs::write(dir.join("moving_media.toml"), text).unwrap();
    let mut args = vec!["check", "moving_media.toml"];
    for s in sets {
        args.extend(["--set", s]);
    }
    let o = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!("{prefix}\nexec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_ohd"))
        .args(&args)
        .current_dir(dir)
        .stdin(std::process::Stdio::null())
        .output()
        .expect("sh starts");
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// Issue 52, item 3: a volume above the memory budget is refused (exit status 2, naming the key,
/// the volume's size and the budget) from its header alone, before anything is allocated. It
/// was read whole and converted before it was counted — four times the budget — and under an
/// address-space limit the allocation aborted (SIGABRT). The files are sparse: nothing here
/// reads or allocates their gigabyte.
#[test]
fn a_npy_volume_above_the_memory_budget_is_refused_before_it_is_read() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // 1 GiB of float32 under a 1 GB address space: the budget is lowered to 3/4 of what is left.
    sparse_npy(&t.join("big.npy"), &[1024, 1024, 256]);
    let density = "media.belt.density={ type = \"npy\", file = \"big.npy\", voxel_size_um = 10 }";
    let (code, e) = check_with(t, "ulimit -v 1000000", &[density]);
    assert_eq!(code, Some(2), "{e}");
    assert!(e.contains("media.belt.density.file") && e.contains("big.npy"), "{e}");
    assert!(e.contains("268435456 voxels") && e.contains("above the memory budget") && e.contains("ulimit -v"), "{e}");
    // The budget the key states, the same way; the velocity as the density.
    let (code, e) = check_with(t, ":", &[density, "run.memory_budget_gib=0.5"]);
    assert_eq!(code, Some(2), "{e}");
    assert!(
        e.contains("media.belt.density.file")
            && e.contains("above the memory budget of 0.5 GiB (run.memory_budget_gib)"),
        "{e}"
    );
    sparse_npy(&t.join("flow.npy"), &[512, 512, 64, 3]);
    let velocity = "media.belt.velocity={ type = \"npy\", file = \"flow.npy\", voxel_size_um = 10 }";
    let (code, e) = check_with(t, ":", &[velocity, "run.memory_budget_gib=0.1"]);
    assert_eq!(code, Some(2), "{e}");
    assert!(e.contains("media.belt.velocity.file") && e.contains("16777216 voxels × 12 bytes"), "{e}");
    assert!(e.contains("above the memory budget of 0.1 GiB (run.memory_budget_gib)"), "{e}");
    // A header whose shape overflows, and one whose data the file does not hold.
    let header = "{'descr': '<f4', 'fortran_order': False, 'shape': (4294967296, 4294967296, 4294967296), }\n";
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((header.len() as u16).to_le_bytes());
    b.extend(header.as_bytes());
    std::fs::write(t.join("huge.npy"), &b).unwrap();
    let (code, e) =
        check_with(t, ":", &["media.belt.density={ type = \"npy\", file = \"huge.npy\", voxel_size_um = 10 }"]);
    assert_eq!(code, Some(2), "{e}");
    assert!(e.contains("media.belt.density.file") && e.contains("overflows"), "{e}");
    std::fs::File::options().write(true).open(t.join("big.npy")).unwrap().set_len(1 << 20).unwrap();
    let (code, e) = check_with(t, ":", &[density]);
    assert_eq!(code, Some(2), "{e}");
    assert!(e.contains("media.belt.density.file") && e.contains("1048576 bytes, where its header"), "{e}");
}
