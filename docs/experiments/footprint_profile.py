import numpy as np
R=30.0; r=0.25; sa=0.75e-3; sc=0.375e-3
def world(ma, mc, step=0.5, reach=5, fine=False):
    # beam axis along +z from origin; sphere centre at (ma, mc, R) (m = centre offset)
    c=np.array([ma,mc,R])
    pts=[]
    if fine:
        g=np.linspace(-4,4,161); step=g[1]-g[0]
        A,C=np.meshgrid(g,g); A=A.ravel(); C=C.ravel()
    else:
        idx=[(i,j) for i in range(-reach,reach+1) for j in range(-reach,reach+1) if i*i+j*j<=reach*reach]
        A=np.array([i*step for i,j in idx]); C=np.array([j*step for i,j in idx])
    w=np.exp(-(A*A+C*C)/2); w/=w.sum()
    d=np.stack([A*sa, C*sc, np.ones_like(A)],1); d/=np.linalg.norm(d,axis=1)[:,None]
    b=d@c; disc=b*b-(c@c-r*r)
    hit=disc>0
    t=b[hit]-np.sqrt(disc[hit])
    p=d[hit]*t[:,None]; n=(p-c)/r; cos=np.abs(np.sum(n*d[hit],1))
    E=w[hit]*cos
    if E.sum()<=0: return None, 0
    rng=(E*t).sum()/E.sum()
    pt=np.array([0,0,rng])
    return np.linalg.norm(pt-c)-r, E.sum()
for fine in (False,True):
  print("fine" if fine else "grid")
  for k in np.arange(-3,3.01,0.25):
    ma=r+k*sa*R
    e,En=world(ma,0.0,fine=fine)
    e2,En2=world(0.0,r+k*sc*R,fine=fine)
    print(f"{k:+.2f} along {e if e is None else e*1e3:8.3f} mm  E {En:.4f} | across {e2 if e2 is None else e2*1e3:8.3f} mm E {En2:.4f}")
