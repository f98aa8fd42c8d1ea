// Messages are published by pointer: a subscriber in the same process (nodelets in one manager)
// receives this very object, without serialisation or a copy; other subscribers get it
// serialised once, as with a message published by value.
#pragma once

#include <boost/make_shared.hpp>
#include <boost/shared_ptr.hpp>
#include <utility>

namespace vwe_vo {

/// Moves `msg` into a shared message to publish (never modified afterwards).
template <typename M>
boost::shared_ptr<const M> sharedMsg(M&& msg) {
  return boost::make_shared<const M>(std::forward<M>(msg));
}

}  // namespace vwe_vo
