#!/usr/bin/env python3
"""Independent references for IMP (common/imp):

1. DBSCAN: ~30 random point sets (Gaussian blobs, slow linear tracks in
   (x, y, t) and uniform noise; 2-D and 3-D; varied eps and min_samples)
   clustered by scikit-learn's sklearn.cluster.DBSCAN (euclidean, default
   algorithm). Acceptance: the C++ labels are identical.
2. Wahba: ~50 random weighted vector sets (full sky and narrow field of view,
   2 to 40 vectors, noise 1 arcsec to 1 deg) solved by scipy's
   Rotation.align_vectors (SVD, independent of Davenport's q-method).
   align_vectors(a, b, w) returns C minimising 1/2 sum w |a - C b|^2, i.e. the
   rotation that maps b onto a; with a = body and b = reference that is
   R_body_from_ref. scipy's quaternion is scalar last [x, y, z, w] (Hamilton,
   same as Eigen); it is written both raw and as the project's [w, x, y, z].
   Acceptance: C++ q-method within 1e-9 rad of scipy.

Writes OUT_DIR/imp_dbscan_sklearn.json and OUT_DIR/imp_wahba_scipy.json.
Exit 77 when packages are missing.
"""
import json
import sys

try:
    import numpy as np
    import scipy
    import sklearn
    from scipy.spatial.transform import Rotation
    from sklearn.cluster import DBSCAN
except ImportError as exc:  # pragma: no cover
    print(f"SKIP: oracle packages not importable with {sys.executable}: {exc}")
    sys.exit(77)

ARCSEC = np.pi / 648000.0


def blobs(rng, dim, n_blobs, extent, std, per_blob):
    pts = []
    for _ in range(n_blobs):
        c = rng.uniform(0.0, extent, dim)
        pts.append(c + std * rng.standard_normal((int(rng.integers(*per_blob)), dim)))
    return pts


def tracks(rng, n_tracks, frames, extent, speed, noise, t_scale):
    """Slowly moving targets over several frames: points (x, y, t_scale * k)."""
    pts = []
    for _ in range(n_tracks):
        p0 = rng.uniform(0.0, extent, 2)
        v = rng.standard_normal(2) * speed
        for k in range(frames):
            xy = p0 + v * k + noise * rng.standard_normal(2)
            pts.append(np.array([[xy[0], xy[1], t_scale * k]]))
    return pts


def dbscan_cases(rng):
    cases = []
    specs = []
    for i in range(24):
        dim = 2 + i % 2
        specs.append(("blobs", dim, i))
    for i in range(4):
        specs.append(("tracks", 3, i))
    specs.append(("lattice_ties", 2, 0))
    specs.append(("small_brute", 2, 0))
    for kind, dim, i in specs:
        if kind == "blobs":
            extent = float(10 ** rng.uniform(1, 3))  # 10 .. 1000 (pixels)
            std = extent * float(rng.uniform(0.003, 0.03))
            parts = blobs(rng, dim, int(rng.integers(1, 7)), extent, std, (4, 60))
            parts.append(rng.uniform(0.0, extent, (int(rng.integers(0, 120)), dim)))
            eps = std * float(rng.uniform(0.6, 2.5))
            min_samples = int(rng.integers(1, 11))
        elif kind == "tracks":
            frames = int(rng.integers(5, 12))
            t_scale = float(rng.uniform(2.0, 6.0))
            parts = tracks(rng, int(rng.integers(2, 6)), frames, 1000.0, 1.5, 0.3, t_scale)
            # Stars / hot pixels that do not persist: uniform in (x, y, frame).
            m = int(rng.integers(50, 300))
            junk = np.column_stack([rng.uniform(0, 1000, (m, 2)),
                                    t_scale * rng.integers(0, frames, m)])
            parts.append(junk)
            # A track point reaches its neighbours in the previous and next
            # frames (t_scale apart, moved ~1.5 sqrt(2) px): n_D = 3 finds
            # tracks through three or more consecutive frames.
            eps = float(np.hypot(t_scale, 4.0) * rng.uniform(1.0, 1.4))
            min_samples = int(rng.integers(2, 4))
        elif kind == "lattice_ties":
            # Integer lattice with holes: many pairs at distance exactly eps.
            g = np.array([[x, y] for x in range(20) for y in range(20)], dtype=float)
            parts = [g[rng.uniform(size=len(g)) < 0.55]]
            eps, min_samples = 2.0, 5
        else:
            # n < 12: scikit-learn switches to brute-force neighbours.
            parts = [rng.uniform(0.0, 3.0, (10, 2))]
            eps, min_samples = 1.0, 3
        X = np.vstack(parts)
        X = X[rng.permutation(len(X))]  # interleave blobs and noise
        model = DBSCAN(eps=eps, min_samples=min_samples, metric="euclidean").fit(X)
        # Smallest relative distance to the eps boundary (ties excepted):
        # tells whether rounding could decide a neighbourhood.
        d2 = ((X[:, None, :] - X[None, :, :]) ** 2).sum(-1)
        rel = np.abs(d2 - eps * eps) / (eps * eps)
        margin = float(rel[rel > 0].min()) if np.any(rel > 0) else 1.0
        cases.append({
            "name": f"{kind}_{dim}d_{i}",
            "eps": eps,
            "min_samples": min_samples,
            "X": X.tolist(),
            "labels": model.labels_.astype(int).tolist(),
            "core_sample_indices": model.core_sample_indices_.astype(int).tolist(),
            "n_clusters": int(model.labels_.max() + 1),
            "min_relative_margin_to_eps2": margin,
            "exact_ties": int(np.count_nonzero(rel == 0)),
        })
    return cases


def wahba_cases(rng):
    cases = []
    for i in range(50):
        n = int(rng.integers(2, 41)) if i % 5 else 2 + i % 3
        narrow = i % 2 == 1
        R = Rotation.random(random_state=int(rng.integers(1 << 31)))
        if narrow:
            # Star tracker: directions within ~8 deg of the boresight.
            b_true = np.column_stack([rng.uniform(-0.14, 0.14, (n, 2)), np.ones(n)])
            b_true /= np.linalg.norm(b_true, axis=1, keepdims=True)
            ref = R.inv().apply(b_true)
        else:
            ref = rng.standard_normal((n, 3))
            ref /= np.linalg.norm(ref, axis=1, keepdims=True)
            if n == 2:
                while abs(ref[0] @ ref[1]) > 0.95:
                    ref[1] = rng.standard_normal(3)
                    ref[1] /= np.linalg.norm(ref[1])
            b_true = R.apply(ref)
        sigma = 10 ** rng.uniform(np.log10(1.0), np.log10(3600.0), n) * ARCSEC
        body = np.empty_like(b_true)
        for k in range(n):
            e1 = np.cross(b_true[k], [1.0, 0.0, 0.0] if abs(b_true[k][0]) < 0.9 else [0.0, 1.0, 0.0])
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(b_true[k], e1)
            v = b_true[k] + sigma[k] * (rng.standard_normal() * e1 + rng.standard_normal() * e2)
            body[k] = v / np.linalg.norm(v)
        weights = 1.0 / sigma ** 2 if i % 3 == 0 else rng.uniform(0.1, 5.0, n)
        C, _rmsd = Rotation.align_vectors(body, ref, weights=weights)
        xyzw = C.as_quat()
        resid = body - C.apply(ref)
        cases.append({
            "name": f"wahba_{i}_{'narrow' if narrow else 'sky'}_{n}",
            "body": body.tolist(),
            "reference": ref.tolist(),
            "weights": weights.tolist(),
            "scipy_as_quat_xyzw": xyzw.tolist(),
            "q_body_from_ref_wxyz": [xyzw[3], xyzw[0], xyzw[1], xyzw[2]],
            "R_body_from_ref": C.as_matrix().tolist(),
            "q_true_body_from_ref_wxyz": [R.as_quat()[3], *R.as_quat()[:3]],
            "wahba_loss": float(0.5 * np.sum(weights * np.sum(resid ** 2, axis=1))),
        })
    return cases


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "."
    rng = np.random.default_rng(20240611)
    db = dbscan_cases(rng)
    with open(f"{out_dir}/imp_dbscan_sklearn.json", "w") as fh:
        json.dump({"source": f"scikit-learn {sklearn.__version__} sklearn.cluster.DBSCAN "
                             "(metric euclidean, algorithm auto; min_samples counts the point "
                             "itself; neighbourhood dist <= eps)",
                   "cases": db}, fh)
    wa = wahba_cases(rng)
    with open(f"{out_dir}/imp_wahba_scipy.json", "w") as fh:
        json.dump({"source": f"scipy {scipy.__version__} Rotation.align_vectors(body, reference, "
                             "weights): C maps reference onto body = R_body_from_ref",
                   "cases": wa}, fh)
    npts = sum(len(c["X"]) for c in db)
    margin = min(c["min_relative_margin_to_eps2"] for c in db)
    ties = sum(c["exact_ties"] for c in db)
    print(f"wrote {len(db)} DBSCAN sets ({npts} points; smallest relative margin to eps^2 "
          f"{margin:.2e}, {ties} exact ties) and {len(wa)} Wahba sets to {out_dir}")


if __name__ == "__main__":
    main()
