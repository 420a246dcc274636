"""COLMAP triangulation (tri/, known poses) -> observation segments in NeuS's normalised space:
one line 'x y z cx cy cz' per (point, observing camera), points filtered by reprojection error
and track length. Usage: prep.py MAXERR MINTRACK OUT"""
import sys, numpy as np
maxerr, mintrack, out = float(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
cams = np.load('scene/cameras_sphere.npz'); S = cams['scale_mat_0']; s = S[0, 0]; c = S[:3, 3]
def qrot(q):
    w, x, y, z = q
    return np.array([[1-2*(y*y+z*z), 2*(x*y-z*w), 2*(x*z+y*w)], [2*(x*y+z*w), 1-2*(x*x+z*z), 2*(y*z-x*w)], [2*(x*z-y*w), 2*(y*z+x*w), 1-2*(x*x+y*y)]])
centres = {}
lines = [l for l in open('tri/images.txt') if not l.startswith('#')]
for l in lines[0::2]:
    f = l.split(); R = qrot(np.array(list(map(float, f[1:5])))); t = np.array(list(map(float, f[5:8])))
    centres[int(f[0])] = -R.T @ t
rows = []
npts = 0
for l in open('tri/points3D.txt'):
    if l.startswith('#'): continue
    f = l.split(); X = np.array(list(map(float, f[1:4]))); err = float(f[7]); track = f[8:]
    imgs = sorted(set(int(track[i]) for i in range(0, len(track), 2)))
    if err > maxerr or len(imgs) < mintrack: continue
    npts += 1
    for i in imgs:
        rows.append(np.concatenate([(X - c) / s, (centres[i] - c) / s]))
np.savetxt(out, np.array(rows), fmt='%.7f')
print(npts, 'points', len(rows), 'observations; scale', s, 'mm per unit')
