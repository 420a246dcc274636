"""ASCII cross-sections of the cup: the truth (left) and a mesh (right) cut by a plane through the
cup axis. Usage: slice.py SCENE MESH [ANGLE_DEG]. Needs trimesh and numpy."""
import sys, os, numpy as np, trimesh
from trimesh.intersections import mesh_plane
sc=sys.argv[1]
g = trimesh.load(sc + '/gt_mesh.ply'); V=g.vertices; c=V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T))
i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
cams=np.load(sc+'/cameras_sphere.npz')
cs=[]
for k in range(49):
    P=cams['world_mat_%d'%k][:3]; M=P[:,:3]; cs.append(-np.linalg.solve(M,P[:,3]))
cs=np.array(cs); md=(cs.mean(0)-c); md-=md@a*a; md/=np.linalg.norm(md)
if (cs.mean(0)-c)@a < 0: a=-a
e2=np.cross(a,md)
ang=float(sys.argv[3]) if len(sys.argv)>3 else 0
u=np.cos(np.radians(ang))*md+np.sin(np.radians(ang))*e2; nrm=np.cross(a,u)
W,H=76,44; cw=2.0; ch=4.0
outs=[]
for name in [sc+'/gt_mesh.ply', sys.argv[2]]:
    m=trimesh.load(name); segs=mesh_plane(m,nrm,c)
    grid=np.full((H,W),' ')
    for s0,s1 in segs:
        for t in np.linspace(0,1,6):
            p=s0+(s1-s0)*t-c; x=p@u; y=p@a
            xi=int((x+76)/cw); yi=int((y+70)/ch)
            if 0<=xi<W and 0<=yi<H: grid[H-1-yi,xi]='#'
    outs.append([''.join(r) for r in grid])
print('left: truth; right:', sys.argv[2], '- plane through the axis at', ang, 'deg from the cameras mean azimuth; x 2 mm/col (+ = camera side), y 4 mm/row (up = the mouth)')
for l,r in zip(*outs): print(l+'|'+r)
