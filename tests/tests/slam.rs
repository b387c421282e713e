//! The SLAM process from the command line.

use shoal_e2e::*;

#[test]
fn a_model_file_with_a_negative_variance_or_bad_weights_is_rejected() {
    let dir = std::env::temp_dir().join(format!("shoal-e2e-model-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch");
    let cases = [
        (
            "negative-variance.toml",
            "[\"walk(2)\"]\nd = { weights = [0.5, 0.5], means = [0.1, 0.2], variances = [-1e-4, 1e-4] }\n\
             c = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n\
             t = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n",
            "toml:2: walk(2).d: variance 0 is -0.0001",
        ),
        (
            "weights.toml",
            "[\"turn(1)\"]\nd = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n\
             c = { weights = [0.5, 0.5], means = [0.0, 0.0], variances = [1e-4, 1e-4] }\n\
             t = { weights = [0.5, 0.7], means = [0.1, 0.2], variances = [1e-4, 1e-4] }\n",
            "toml:4: turn(1).t: weights sum to 1.2",
        ),
    ];
    for (name, text, expected) in cases {
        let path = dir.join(name);
        std::fs::write(&path, text).expect("write the model");
        let output = shoal(&[
            "slam",
            "--follow",
            "0",
            "--initial-model",
            path.to_str().expect("utf-8"),
        ]);
        assert!(!output.status.success(), "{name} was accepted");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            stderr.contains(name) && stderr.contains(expected),
            "{name}: {stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(dir);
}
