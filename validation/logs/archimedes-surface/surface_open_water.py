import numpy as np, sys
f = open(sys.argv[1],'rb').read()
h = f.index(b'end_header\n')+len(b'end_header\n')
dt = np.dtype([('x','<f4'),('y','<f4'),('z','<f4'),('vx','<f4'),('vy','<f4'),('vz','<f4'),('m','<i4'),('p','<f4')])
a = np.frombuffer(f[h:], dtype=dt)
dx = float(sys.argv[2]); cx=cz=0.3; half=0.06
for nb, nw in [(3,3),(5,3),(3,5),(2,2)]:
    db = np.maximum(np.abs(a['x']-cx)-half, np.abs(a['z']-cz)-half)
    X=a['x'];Y=a['y'];Z=a['z']
    ix=np.floor(X/dx).astype(int); iz=np.floor(Z/dx).astype(int); key=ix*100000+iz
    order=np.lexsort((Y,key)); k=key[order]; yy=Y[order]; last=np.r_[k[1:]!=k[:-1],True]; t=yy[last]; kk=k[last]
    cxs=(kk//100000)*dx; czs=(kk%100000)*dx  # column lower corner
    # column fully >= nw cells from walls (0.06..0.54) and >= nb cells from the box footprint
    dw=np.minimum(np.minimum(cxs-0.06,0.54-(cxs+dx)),np.minimum(czs-0.06,0.54-(czs+dx)))
    dbx=np.maximum(np.maximum(cxs-(cx+half), (cx-half)-(cxs+dx)), np.maximum(czs-(cz+half),(cz-half)-(czs+dx)))
    s=(dw>=nw*dx-1e-6)&(dbx>=nb*dx-1e-6)
    print(f"box>={nb} cells, walls>={nw} cells: n {s.sum()} median {np.median(t[s])+dx/4:.5f}")
