import json,sys
sc=['blob','torus','thin','blocks','relief','double-torus','plate','rods']
def get(p):
    try: m=json.load(open(p+'/metrics.json'))
    except Exception: return None
    return m
rows=[]
rs={'fast':[], 'd5':[], 'd20':[]}
print('| scene | floor (mm) | `fast` | `train.depth.weight=5` | weight 20 |')
print('|---|---|---|---|---|')
for s in sc+['cup']:
    f=get('r/%s_fast'%s) if s!='cup' else get('r/fast0')
    d=get('r/%s_d5_s0'%s) if s!='cup' else get('r/d1_cup')
    w=get('r/%s_d20_s0'%s) if s!='cup' else get('r/d1_w20')
    def cell(m):
        if m is None: return '–'
        return '%.3f (%.2f×, genus %s/%s)'%(m['chamfer']['chamfer_sum'],m['ratio_to_floor'],m['mesh']['largest_genus'],m['gt_genus'])
    fl=f['floor_mm']
    print('| %s | %.3f | %s | %s | %s |'%(s,fl,cell(f),cell(d),cell(w)))
    if f and d:
        rs['fast'].append((s,f['ratio_to_floor'])); rs['d5'].append((s,d['ratio_to_floor']))
import statistics as st
for k in ['fast','d5']:
    v=[r for s,r in rs[k]]; v8=[r for s,r in rs[k] if s!='cup']
    print(k,'mean ratio all %.2f (n=%d), without cup %.2f'%(st.mean(v),len(v),st.mean(v8)))
