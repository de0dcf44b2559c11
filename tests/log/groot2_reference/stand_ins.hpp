// The stand-in leaves both reference recorders register: Countdown and Tally, the same nodes as
// tests/log/groot2_support.py writes for chaser-bt.
#pragma once

#include <behaviortree_cpp/bt_factory.h>

#include <string>

namespace stand_ins
{
class Countdown : public BT::StatefulActionNode
{
public:
  Countdown(const std::string& name, const BT::NodeConfig& config)
    : BT::StatefulActionNode(name, config)
  {}

  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<int>("ticks", 2, "ticks to stay RUNNING") };
  }

  BT::NodeStatus onStart() override
  {
    remaining_ = getInput<int>("ticks").value();
    return onRunning();
  }

  BT::NodeStatus onRunning() override
  {
    if(remaining_ == 0)
    {
      return BT::NodeStatus::SUCCESS;
    }
    remaining_--;
    return BT::NodeStatus::RUNNING;
  }

  void onHalted() override
  {}

private:
  int remaining_ = 0;
};

class Tally : public BT::SyncActionNode
{
public:
  Tally(const std::string& name, const BT::NodeConfig& config) : BT::SyncActionNode(name, config)
  {}

  static BT::PortsList providedPorts()
  {
    return { BT::InputPort<int>("add", 1, "amount to add"),
             BT::OutputPort<int>("total", "{tally}", "the amount, written") };
  }

  BT::NodeStatus tick() override
  {
    setOutput("total", getInput<int>("add").value());
    return BT::NodeStatus::SUCCESS;
  }
};
}  // namespace stand_ins
