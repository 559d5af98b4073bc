//! Replays the fuzz seed corpora (`fuzz/seeds/<target>/`) and every input that once found a
//! bug through the same entry points as the fuzz targets: an error or a success, never a
//! panic. Runs on stable in ordinary `cargo test`.

use std::ffi::OsString;
use std::os::unix::ffi::OsStringExt;
use std::path::Path;

fn corpus(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds").join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{}: empty corpus", dir.display());
    files.into_iter().map(|p| (p.display().to_string(), std::fs::read(&p).unwrap())).collect()
}

#[test]
fn cli_args_corpus_never_panics() {
    for (name, data) in corpus("cli_args") {
        let args: Vec<OsString> = data.split(|&b| b == 0).map(|a| OsString::from_vec(a.to_vec())).collect();
        let result = std::panic::catch_unwind(|| residual_nerf::cli::parse(args));
        let parsed = result.unwrap_or_else(|_| panic!("{name}: the parser panicked"));
        if let Err(e) = parsed {
            assert!(!e.0.contains('\n'), "{name}: error is not one line: {e}");
        }
    }
}

/// Runs `f` on every input of `target`'s corpus, failing on a panic.
fn replay(target: &str, f: impl Fn(&[u8]) + std::panic::RefUnwindSafe) {
    for (name, data) in corpus(target) {
        if std::panic::catch_unwind(|| f(&data)).is_err() {
            panic!("{name}: a parser panicked");
        }
    }
}

#[test]
fn transforms_json_corpus_never_panics() {
    replay("transforms_json", |data| {
        if let Err(errors) = residual_nerf::data::transforms::parse_transforms(data, Path::new("fuzz/transforms.json"))
        {
            assert!(!errors.is_empty());
            let line = residual_nerf::data::DataReport(errors).to_string();
            assert!(!line.contains('\n'), "error is not one line: {line}");
        }
    });
}

#[test]
fn colmap_model_corpus_never_panics() {
    use residual_nerf::data::colmap;
    replay("colmap_model", |data| {
        let lines = [
            colmap::cameras_txt(data).err(),
            colmap::images_txt(data).err(),
            colmap::points_txt(data).err(),
            colmap::cameras_bin(data).err(),
            colmap::images_bin(data).err(),
            colmap::points_bin(data).err(),
        ];
        for line in lines.into_iter().flatten() {
            assert!(!line.contains('\n'), "error is not one line: {line}");
        }
    });
}

#[test]
fn image_corpus_never_panics() {
    use residual_nerf::data::images;
    replay("image_decode", |data| {
        let _ = images::decode_rgb(data, [1.0; 3]);
        let _ = images::decode_mask(data);
        let _ = images::decode_depth_exr(data);
    });
}

#[test]
fn model_file_corpus_never_panics() {
    replay("model_file", |data| {
        if let Err(e) = residual_nerf::io::model_from_bytes(data) {
            assert!(!e.message().contains('\n'), "error is not one line: {e}");
        }
        if let Err(e) = residual_nerf::io::checkpoint_from_bytes(data) {
            assert!(!e.contains('\n'), "error is not one line: {e}");
        }
    });
}
