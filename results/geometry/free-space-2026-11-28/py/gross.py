import numpy as np,sys
for d in sys.argv[1:]:
    s=float(open(d+'/scale.txt').read()); out=[]
    agg={}
    for v in range(46):
        t=np.fromfile(f'{d}/t{v:02}.f32',np.float32); g=np.fromfile(f'{d}/g{v:02}.f32',np.float32)
        p=np.fromfile(f'{d}/p{v:02}.u8',np.uint8)
        ok=np.isfinite(g); e=(t-g)*s
        for part in range(4):
            m=ok&(p==part); a=agg.setdefault(part,np.zeros(6))
            ee=e[m]; fin=np.isfinite(ee)
            a+= [m.sum(), (~fin).sum(), (ee[fin]<-10).sum(), (ee[fin]>10).sum(), ((ee[fin]<-2)&(ee[fin]>=-10)).sum(), ((ee[fin]>2)&(ee[fin]<=10)).sum()]
    print(d, ' | '.join('%s: miss %d F10 %d B10 %d F2 %d B2 %d'%(n,a[1],a[2],a[3],a[4],a[5]) for n,a in zip(['bot','in','out','oth'],[agg[i] for i in range(4)])))
