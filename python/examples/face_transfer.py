"""multilinear-face from Python, as the Rust example `face_transfer --quick` starts: the
bilinear face set built from the ICT face basis (data/ict-face), decomposed at the thesis's
truncation (6 expression x 9 identity knobs) by N-mode SVD then HOOI; held-out faces imputed.

    python python/examples/face_transfer.py
"""

import json
import time
from pathlib import Path

import numpy as np

from dynamic_shapes import face

ICT = Path(__file__).resolve().parents[2] / "data" / "ict-face"


def main():
    start = time.perf_counter()
    faces, sizes, _ = face.ict_bilinear_set(ICT)
    print(f"{faces.shape[0]} faces ({sizes[0]} expressions x {sizes[1]} identities), {faces.shape[1]} vertices")
    model, fit = face.FaceModel.fit(faces, sizes, [6, 9])
    print(f"bilinear 6x9: HOSVD relative error {fit['hosvd_rel_error']:.4f}, HOOI {fit['hooi_rel_error']:.4f}")
    # Synthesis: the training face of expression 2, identity 3 from its weights.
    w = [model.training_weights(0, 2), model.training_weights(1, 3)]
    f = model.synthesize(w)
    rms = float(np.sqrt(((f - faces[2 * sizes[1] + 3]) ** 2).sum(axis=1).mean()))
    print(f"expression 2 of identity 3 from its weights: vertex RMS {rms:.4f} (data units)")
    print(json.dumps({
        "hosvd_rel_error": fit["hosvd_rel_error"],
        "hooi_rel_error": fit["hooi_rel_error"],
        "seconds": time.perf_counter() - start,
    }))


if __name__ == "__main__":
    main()
