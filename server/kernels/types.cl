#include "shared/correspondence.h"
#include "shared/features.h"
#include "shared/icp.h"
#include "shared/solver.h"
#include "shared/tsdf.h"

/* Reports the device's view of the shared struct sizes, checked against the host's in a test. */
__kernel void vd_type_sizes(__global int* out, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  out[0] = (int)sizeof(VdCamera);
  out[1] = (int)sizeof(VdPose);
  out[2] = (int)sizeof(VdVolume);
  out[3] = (int)sizeof(VdIcpParams);
  out[4] = (int)sizeof(float4);
  out[5] = (int)sizeof(VdCorrespondence);
  out[6] = (int)sizeof(VdCorrParams);
  out[7] = (int)sizeof(VdLiftParams);
  out[8] = (int)sizeof(VdSolverWeights);
  out[9] = (int)sizeof(VdMatchBest);
  out[10] = (int)sizeof(VdMat3);
  out[11] = (int)sizeof(VdFusionParams);
  out[12] = (int)sizeof(VdLattice);
}
