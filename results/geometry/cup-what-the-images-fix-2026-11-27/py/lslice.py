import sys, json, numpy as np, trimesh
sc, hd = sys.argv[1], sys.argv[2]
g = json.load(open(hd + '/grid.json')); gmin = np.array(g['min']); h = g['h']; res = g['res']
L = np.fromfile(hd + '/labels.u8', dtype=np.uint8).reshape(res[2], res[1], res[0])
print('label counts', np.bincount(L.ravel()), 'voxel mm3', h**3)
P=np.array(json.load(open(f'{sc}/meta.json'))['gt']['plane']); n=P[:3]/np.linalg.norm(P[:3])
v=np.asarray(trimesh.load(f'{sc}/gt_mesh.ply').vertices); base=(v@n).min()
c=v.mean(0); c=c-n*(c@n)
cams=np.load(sc+'/cameras_sphere.npz'); cs=[]
for k in range(49):
    Pm=cams['world_mat_%d'%k][:3]; cs.append(-np.linalg.solve(Pm[:,:3],Pm[:,3]))
cs=np.array(cs); md=cs.mean(0)-c; md-=md@n*n; md/=np.linalg.norm(md)
ang=np.radians(float(sys.argv[3]) if len(sys.argv)>3 else 0.0)
e=np.cos(ang)*md+np.sin(ang)*np.cross(n,md)
rows=[]
for zz in np.arange(175, -6, -3.0):
    row=''
    for xx in np.arange(-76, 77, 2.0):
        p=c+e*xx+n*(base+zz)
        gi=np.round((p-gmin)/h).astype(int)
        if np.any(gi<0) or np.any(gi>=np.array(res)): row+=' '; continue
        row+=' o#'[L[gi[2],gi[1],gi[0]]]
    rows.append(row)
print('\n'.join(rows))
