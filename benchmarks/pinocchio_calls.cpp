// The closed loop's Pinocchio calls as C functions, for benchmarks/compiled_floor.py.
//
// Each function makes, through Pinocchio's C++ API, exactly the calls that one part of the loop
// makes through Pinocchio's Python bindings, on the same pin.Model and pin.Data objects (their
// addresses come from the small Python module below). Compiled code (Numba) calls them through
// their addresses, so the benchmark can time what the calls cost with no Python in between.
// Arrays are NumPy's: C order, float64.

#include <boost/python.hpp>
#include <cstdint>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>

namespace {

using Model = pinocchio::Model;
using Data = pinocchio::Data;
using Vector = Eigen::Map<const Eigen::VectorXd>;
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

}  // namespace

extern "C" {

// The control step's calls (pbvs_pin.control.step.FusedControlStep.step): joint Jacobians, the
// camera placement and its LOCAL Jacobian (written to jacobian, shape (6, nv)), CRBA, nonlinear
// effects at v_pin, gravity. The mass matrix and the two vectors stay in data, as in Python.
void control_calls(const void* model_address, void* data_address, long frame, const double* q,
                   const double* v_pin, double* jacobian) {
  const Model& model = *static_cast<const Model*>(model_address);
  Data& data = *static_cast<Data*>(data_address);
  const Vector configuration(q, model.nq), velocity(v_pin, model.nv);
  Eigen::Map<RowMajor> frame_jacobian(jacobian, 6, model.nv);
  pinocchio::computeJointJacobians(model, data, configuration);
  pinocchio::updateFramePlacement(model, data, frame);
  frame_jacobian.setZero();
  pinocchio::getFrameJacobian(model, data, frame, pinocchio::LOCAL, frame_jacobian);
  pinocchio::crba(model, data, configuration);
  pinocchio::nonLinearEffects(model, data, configuration, velocity);
  pinocchio::computeGeneralizedGravity(model, data, configuration);
}

// The plant step's calls (pbvs_pin.plant.pinocchio_plant.Plant.step): CRBA, nonlinear effects, gravity, then
// q_next = integrate(q, displacement), shape (nq,).
void plant_calls(const void* model_address, void* data_address, const double* q,
                 const double* v_pin, const double* displacement, double* q_next) {
  const Model& model = *static_cast<const Model*>(model_address);
  Data& data = *static_cast<Data*>(data_address);
  const Vector configuration(q, model.nq), velocity(v_pin, model.nv);
  pinocchio::crba(model, data, configuration);
  pinocchio::nonLinearEffects(model, data, configuration, velocity);
  pinocchio::computeGeneralizedGravity(model, data, configuration);
  Eigen::Map<Eigen::VectorXd> next(q_next, model.nq);
  pinocchio::integrate(model, configuration, Vector(displacement, model.nv), next);
}

// The prediction's call (pbvs_pin.model.robot.MobileManipulator.camera_placement): forward kinematics
// and the camera frame's placement, written as rotation (3, 3) and translation (3,).
void camera_placement(const void* model_address, void* data_address, long frame, const double* q,
                      double* rotation, double* translation) {
  const Model& model = *static_cast<const Model*>(model_address);
  Data& data = *static_cast<Data*>(data_address);
  pinocchio::forwardKinematics(model, data, Vector(q, model.nq));
  const pinocchio::SE3& placement = pinocchio::updateFramePlacement(model, data, frame);
  Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> rotation_out(rotation);
  Eigen::Map<Eigen::Vector3d> translation_out(translation);
  rotation_out = placement.rotation();
  translation_out = placement.translation();
}

}  // extern "C"

namespace {

std::uintptr_t model_address(boost::python::object model) {
  return reinterpret_cast<std::uintptr_t>(&boost::python::extract<Model&>(model)());
}

std::uintptr_t data_address(boost::python::object data) {
  return reinterpret_cast<std::uintptr_t>(&boost::python::extract<Data&>(data)());
}

boost::python::dict function_addresses() {
  boost::python::dict addresses;
  addresses["control_calls"] = reinterpret_cast<std::uintptr_t>(&control_calls);
  addresses["plant_calls"] = reinterpret_cast<std::uintptr_t>(&plant_calls);
  addresses["camera_placement"] = reinterpret_cast<std::uintptr_t>(&camera_placement);
  return addresses;
}

}  // namespace

BOOST_PYTHON_MODULE(pinocchio_calls) {
  boost::python::def("model_address", model_address);
  boost::python::def("data_address", data_address);
  boost::python::def("function_addresses", function_addresses);
}
