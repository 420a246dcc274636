import sys, trimesh
from trimesh import smoothing
src,dst,it=sys.argv[1],sys.argv[2],int(sys.argv[3])
lam=float(sys.argv[4]) if len(sys.argv)>4 else 0.5
m=trimesh.load(src,process=False)
smoothing.filter_taubin(m,lamb=lam,nu=0.53,iterations=it)
m.export(dst)
