//! Scratch: measurements.
#![allow(clippy::unwrap_used, clippy::print_stdout)]
use dynamic_shapes::face::validation::*;
use dynamic_shapes::face::*;

#[test]
fn scratch() {
    let basis = IctBasis::read(example_kit::data_path("ict-face").unwrap()).unwrap();
    let bi = bilinear_face_set(&basis, &FaceSetParams::default()).unwrap();
    let tri = trilinear_face_set(&basis, &FaceSetParams::default().with_identities(16)).unwrap();
    for (name, set) in [("bi", &bi), ("tri", &tri)] {
        for frac in [0.15, 0.5] {
            let known = hold_out(set.faces.attribute_sizes(), frac, 7).unwrap();
            let avg = impute_by_averaging(&set.faces, &known).unwrap();
            println!("{name} {frac}: avg {:.4}", impute_rel_error(&set.faces, &avg, &known).unwrap());
            for energy in [0.99, 0.999, 0.9999, 0.99999] {
                for em in [true, false] {
                let p = ImputeParams { energy, em_covariance: em, ..ImputeParams::default() };
                let ours = impute(&set.faces, &known, &p).unwrap();
                println!("   e {energy} em {em} ours {:.4} it {} ranks {:?}", impute_rel_error(&set.faces, &ours.faces, &known).unwrap(), ours.iterations, ours.ranks);
                }
            }
        }
    }
}
