"""Why the thesis's noise-free 2-motion results are not exact: the explanations tested in docs/chapter5.md.

    python docs/chapter5_why.py

Prints, for 200 noise-free §5.2 scenes per motion count, Daniilidis's error (median, 10th percentile,
worst) computed by handeye (float64), in single precision (metres and millimetres), on poses rounded
to 0.01 mm / 0.01 deg, with the thesis's root criterion as printed in §2.2.3, and with the §4.1.2
assembly taken literally. Experiments only: not part of the package.
"""
import numpy as np
from scipy.spatial.transform import Rotation
from handeye.simulate import seed_scenes
from handeye.workflows.study import pose_errors, _motions
from handeye.geometry.dualquat import dq_from_matrix, dq_to_matrix
from handeye.solvers import solve_batch
from handeye.frames.motions import _align_signs
from handeye.solvers.daniilidis import _blocks
from handeye.frames.motions import MotionSet

def dan_dtype(A, B, dtype, unit=1.0):
    A = A.copy(); B = B.copy(); A[..., :3, 3] *= unit; B[..., :3, 3] *= unit
    A = A.astype(dtype); B = B.astype(dtype)
    qa = dq_from_matrix(A.astype(np.float64)).astype(dtype); qb = dq_from_matrix(B.astype(np.float64)).astype(dtype)
    qa, qb = _align_signs(qa, qb)
    T = _blocks(qa, qb).astype(dtype).reshape(len(A), -1, 8)
    _, s, vt = np.linalg.svd(T)
    X = np.full((len(A),4,4), np.nan)
    for k in range(len(A)):
        u1,v1,u2,v2 = vt[k,6,:4],vt[k,6,4:],vt[k,7,:4],vt[k,7,4:]
        a=u1@v1; b=u1@v2+u2@v1; c=u2@v2
        disc=max(b*b-4*a*c,0)
        best=None
        for sgn in (1,-1):
            s_=(-b+sgn*np.sqrt(disc))/(2*a)
            val=s_*s_*(u1@u1)+2*s_*(u1@u2)+u2@u2
            if best is None or val>best[0]: best=(val,s_)
        val,s_=best; l2=1/np.sqrt(val); l1=s_*l2
        dq=(l1*vt[k,6]+l2*vt[k,7]).astype(np.float64)
        M=dq_to_matrix(dq/np.linalg.norm(dq[:4])); M[:3,3]/=unit
        X[k]=M
    return X

def thesis_variants(A, B):
    ms = MotionSet.from_matrices(A, B)
    T = _blocks(ms.dq_a, ms.dq_b).reshape(len(A), -1, 8)
    _, s, vt = np.linalg.svd(T)
    out = {k: np.full((len(A), 4, 4), np.nan) for k in ("2.2.3 as printed", "4.1.2 assembly q=l1 v7, q'=l2 v8")}
    for k in range(len(A)):
        v7, v8 = vt[k, 6], vt[k, 7]
        u1, v1, u2, v2 = v7[:4], v7[4:], v8[:4], v8[4:]
        a, b, c = u1 @ v1, u1 @ v2 + u2 @ v1, u2 @ v2
        roots = np.roots([a, b, c]) if abs(a) > 0 else np.array([-c / b])
        roots = roots[np.isreal(roots)].real
        if len(roots) == 0:
            continue
        f = roots**2 * (u1 @ u1) + 2 * roots * (u1 @ u2) + u2 @ u2
        sp = roots[np.argmax(f)]
        l2 = 1 / np.sqrt(f.max()); l1 = sp * l2
        dq = l1 * v7 + l2 * v8
        out["2.2.3 as printed"][k] = dq_to_matrix(dq / np.linalg.norm(dq[:4]))
        dq2 = np.r_[(l1 * v7)[:4], (l2 * v8)[4:]]
        out["4.1.2 assembly q=l1 v7, q'=l2 v8"][k] = dq_to_matrix(dq2 / np.linalg.norm(dq2[:4]))
    return out

rng=np.random.default_rng(5)
for n in (2,3,4,6,15):
    sc=seed_scenes(200, n+1, "eye_in_hand", rng)
    A,B=_motions(sc.flange2base, sc.target2cam, "eye_in_hand")
    rows={}
    rows["float64 m (handeye)"]=pose_errors(solve_batch(A,B,"daniilidis"), sc.X)
    rows["float32 m"]=pose_errors(dan_dtype(A,B,np.float32,1.0), sc.X)
    rows["float32 mm"]=pose_errors(dan_dtype(A,B,np.float32,1000.0), sc.X)
    # quantised robot poses: 0.01 mm, 0.01 deg (xyz + ZYX euler as a pendant shows)
    f=sc.flange2base.copy()
    e=Rotation.from_matrix(f[...,:3,:3].reshape(-1,3,3)).as_euler("ZYX",degrees=True)
    f[...,:3,:3]=Rotation.from_euler("ZYX",np.round(e,2),degrees=True).as_matrix().reshape(f[...,:3,:3].shape)
    f[...,:3,3]=np.round(f[...,:3,3]*1e5)/1e5
    A2,B2=_motions(f, sc.target2cam, "eye_in_hand")
    rows["poses rounded 0.01mm/0.01deg"]=pose_errors(solve_batch(A2,B2,"daniilidis"), sc.X)
    for name, X in thesis_variants(A, B).items():
        rows[name] = pose_errors(X, sc.X)
    for k,e in rows.items():
        print(n, k.ljust(30), "median %.3g mm / %.3g deg  p10 %.3g / %.3g  max %.3g / %.3g" % (np.median(e[:,0]), np.median(e[:,1]), np.percentile(e[:,0],10), np.percentile(e[:,1],10), e[:,0].max(), e[:,1].max()))
