import numpy as np,sys
d=sys.argv[1]; s=float(open(d+'/scale.txt').read()); W,H=400,300
rows=[]
for v in range(46):
    t=np.fromfile(f'{d}/t{v:02}.f32',np.float32).reshape(H,W); g=np.fromfile(f'{d}/g{v:02}.f32',np.float32).reshape(H,W)
    f=np.fromfile(f'{d}/f{v:02}.u8',np.uint8).reshape(H,W); p=np.fromfile(f'{d}/p{v:02}.u8',np.uint8).reshape(H,W)
    sx=np.full_like(g,np.nan); sy=np.full_like(g,np.nan)
    sx[:,1:-1]=np.abs(g[:,2:]-g[:,:-2])/2; sy[1:-1,:]=np.abs(g[2:,:]-g[:-2,:])/2
    sl=np.fmax(sx,sy)*s
    # distance to nearest stereo pixel? count stereo (f==0 finite) in 3x3
    st=(np.isfinite(t)&(f==0)).astype(int); c=np.zeros_like(st)
    for dy in (-1,0,1):
      for dx in (-1,0,1): c+=np.roll(np.roll(st,dy,0),dx,1)
    m=np.isfinite(t)&np.isfinite(g)&(f==1)&((p==1)|(p==2))
    e=((t-g)*s)[m]; rows.append(np.stack([e,sl[m],c[m]],1))
r=np.concatenate(rows)
e,sl,c=r[:,0],r[:,1],r[:,2]
for name,mm in [('good',np.abs(e)<2),('front2-10',(e<=-2)&(e>-10)),('front>10',e<=-10),('behind',e>=2)]:
    print(name, mm.sum(), 'slope mm/px q25/50/75 %.2f %.2f %.2f'%tuple(np.nanpercentile(sl[mm],[25,50,75])), 'stereo nbrs mean %.2f'%c[mm].mean())
